#!/usr/bin/env bash
# Installs the Debian packages activefoam builds with. Idempotent: installs only what is missing,
# and runs apt-get update only when something is missing.
set -euo pipefail
pkgs=(build-essential cmake ninja-build pkg-config git
      libeigen3-dev libspdlog-dev libsqlite3-dev libcli11-dev nlohmann-json3-dev
      libtomlplusplus-dev libgtest-dev libgmock-dev libbenchmark-dev gnuplot-nox python3
      libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler grpc-proto
      zlib1g-dev bsdextrautils
      python3-grpcio python3-protobuf python3-pandas python3-pytest  # the Python client's tests
      clang libomp-dev)  # the tsan preset: clang + LLVM's libomp, whose Archer tool TSan understands
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup-deps: all ${#pkgs[@]} packages present"
  exit 0
fi
echo "setup-deps: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
