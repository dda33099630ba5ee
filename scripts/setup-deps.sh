#!/usr/bin/env bash
# Installs the Debian packages activefoam builds with. Idempotent: installs only what is missing,
# and runs apt-get update only when something is missing.
#   scripts/setup-deps.sh          what the build and the main job need
#   scripts/setup-deps.sh --tests  also what only some tests use (a browser, Prometheus)
set -euo pipefail
tests=false
[ "${1:-}" = "--tests" ] && tests=true
pkgs=(build-essential cmake ninja-build pkg-config git
      libeigen3-dev libspdlog-dev libsqlite3-dev libcli11-dev nlohmann-json3-dev
      libtomlplusplus-dev libgtest-dev libgmock-dev libbenchmark-dev gnuplot-nox python3
      libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler grpc-proto
      zlib1g-dev bsdextrautils libcpp-httplib-dev libssl-dev libjs-chart.js
      libgrpc-dev libabsl-dev libc-ares-dev libre2-dev  # their static archives: foam's link
      libjs-three  # the dashboard's 3D view (three.js r111), compiled into foamd
      ffmpeg  # foam export --movie and Job.movie encode with it; its ffprobe checks them
      python3-grpcio python3-protobuf python3-pandas python3-pytest  # the Python client's tests
      python3-yaml python3-jsonschema  # CITATION.cff against its schema (tests/repo)
      python3-venv  # its install test: pip install ./python into a fresh virtual environment
      python3-matplotlib  # study reports (python3 -m activefoam.study report)
      python3-scipy  # the science pages' fits and rotations (docs/science/*/*.py)
      python3-tqdm  # progress bars of Job.wait / Sweep.wait (a plain line without it)
      clang libomp-dev  # the tsan preset: clang + LLVM's libomp, whose Archer tool TSan understands
      ccache)  # the compiler launcher (CMakeLists.txt): builds reuse earlier builds' objects
# Only some tests use these (the dashboard in a real browser, a real Prometheus scraping foamd);
# where they cannot be installed, those tests report skipped.
optional=()
$tests && optional=(chromium fonts-dejavu-core prometheus)
missing=() missing_optional=()
installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
for p in "${pkgs[@]}"; do installed "$p" || missing+=("$p"); done
for p in "${optional[@]+"${optional[@]}"}"; do installed "$p" || missing_optional+=("$p"); done
if [ ${#missing[@]} -eq 0 ] && [ ${#missing_optional[@]} -eq 0 ]; then
  echo "setup-deps: all $((${#pkgs[@]} + ${#optional[@]})) packages present"
  exit 0
fi
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup-deps: installing ${missing[*]}"
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
if [ ${#missing_optional[@]} -gt 0 ]; then
  echo "setup-deps: installing (optional) ${missing_optional[*]}"
  $SUDO apt-get install -y -qq --no-install-recommends "${missing_optional[@]}" ||
    echo "setup-deps: could not install ${missing_optional[*]}: the dashboard and Prometheus" \
      "tests will report skipped"
fi
