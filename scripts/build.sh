#!/usr/bin/env bash
# Installs missing Debian packages, then configures and builds one CMake preset (default release).
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
./scripts/setup-deps.sh
cmake --preset "$preset" >/dev/null
cmake --build --preset "$preset" -j "$(nproc)"
