#!/usr/bin/env bash
# The test command of the README (and of CI): install, build, run every test.
#   scripts/test.sh          release build, all tests
#   scripts/test.sh asan     AddressSanitizer + UBSan build, engine tests only
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
./scripts/build.sh "$preset"
label=()
[ "$preset" = asan ] && label=(-L engine)
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
ctest --preset "$preset" -j "$(nproc)" "${label[@]}"
