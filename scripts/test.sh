#!/usr/bin/env bash
# The test command of the README (and of CI): install, build, run every test.
#   scripts/test.sh          release build, all tests
#   scripts/test.sh asan     AddressSanitizer + UBSan build, engine tests only
#   scripts/test.sh tsan     ThreadSanitizer build (clang + libomp/Archer), engine tests only,
#                            every test on 2 OpenMP threads
#   scripts/test.sh asan-server  AddressSanitizer + UBSan build of foamd, foam and their tests;
#                            runs the in-process server tests (gRPC service, HTTP, store)
#                            (all of them: ctest --preset asan-server -L 'server|faults', ~14 min)
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
# The tests' own packages (a browser for the dashboard, Prometheus): the main job needs neither.
./scripts/setup-deps.sh --tests
./scripts/build.sh "$preset"
label=()
[ "$preset" = asan ] && label=(-L engine)
# The tests that run foamd in-process: the ones that spawn processes and engine runs add
# ~12 min under ASan and exercise the same server code.
[ "$preset" = asan-server ] &&
  label=(-R '^(ServiceTest|HttpTest|HttpListener|GrpcListener|Store|JobStates|Utf8|SpecConvert)\.')
# The doublet contact-angle relaxations take minutes under TSan's ~10x slowdown and run the same
# kernels as the short tests (the Threads.* tests run every parallel path on small scenes).
[ "$preset" = tsan ] && label=(-L engine -E 'DoubletContactAngle')
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
# libomp itself is not instrumented (Archer supplies its synchronisation): TSan must not report
# races inside it, which is what Archer asks for.
export TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:ignore_noninstrumented_modules=1
ctest --preset "$preset" -j "$(nproc)" "${label[@]}"
