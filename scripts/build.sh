#!/usr/bin/env bash
# Installs missing Debian packages, then configures and builds one CMake preset (default release).
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
./scripts/setup-deps.sh
# ccache (the compiler launcher when installed): paths below the checkout are hashed relative to
# it, so that another clone of the same commit (CI's) finds this one's objects.
export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
cmake --preset "$preset" >/dev/null
cmake --build --preset "$preset" -j "$(nproc)"
