#!/usr/bin/env bash
# The Python client's gRPC stubs (python/activefoam/v1/*_pb2*.py), generated from proto/ with
# Debian's protoc and grpc_python_plugin (protobuf-compiler, protobuf-compiler-grpc). They are
# committed, so that `pip install ./python` needs no protoc; run this after changing proto/.
#
#   scripts/python-stubs.sh           regenerate them
#   scripts/python-stubs.sh --check   exit 1 naming the stubs that differ from what proto/ gives
#                                     (77: protoc or the plugin missing)
#
# PROTOC and GRPC_PYTHON_PLUGIN name other binaries (ctest passes the build's).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
check=0
[ "${1:-}" = --check ] && check=1
protoc="${PROTOC:-$(command -v protoc || true)}"
plugin="${GRPC_PYTHON_PLUGIN:-$(command -v grpc_python_plugin || true)}"
if [ ! -x "$protoc" ] || [ ! -x "$plugin" ]; then
  echo "python-stubs: protoc or grpc_python_plugin missing (apt-get install protobuf-compiler" \
       "protobuf-compiler-grpc)" >&2
  exit 77
fi
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
v1="$root/proto/activefoam/v1"
"$protoc" --proto_path="$root/proto" --python_out="$tmp" "$v1/job.proto" "$v1/scene.proto" \
  "$v1/service.proto"
# Only service.proto declares a service: its stub is the one *_pb2_grpc.py.
"$protoc" --proto_path="$root/proto" --grpc_python_out="$tmp" \
  --plugin=protoc-gen-grpc_python="$plugin" "$v1/service.proto"
out="$root/python/activefoam/v1"
if [ "$check" = 0 ]; then
  rm -f "$out"/*_pb2.py "$out"/*_pb2_grpc.py
  cp "$tmp"/activefoam/v1/*.py "$out"/
  exit 0
fi
bad=()
for f in "$tmp"/activefoam/v1/*.py; do
  cmp -s "$f" "$out/$(basename "$f")" || bad+=("$(basename "$f")")
done
for f in "$out"/*_pb2.py "$out"/*_pb2_grpc.py; do
  [ -e "$f" ] && [ ! -e "$tmp/activefoam/v1/$(basename "$f")" ] && bad+=("$(basename "$f") (no proto)")
done
if [ "${#bad[@]}" -gt 0 ]; then
  echo "python-stubs: python/activefoam/v1 differs from proto/ in: ${bad[*]}; run" \
       "scripts/python-stubs.sh and commit the result" >&2
  exit 1
fi
echo "python-stubs: python/activefoam/v1 matches proto/"
