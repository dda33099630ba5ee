#!/usr/bin/env bash
# The main job of the README: install, build, and run a small job with the engine's batch runner,
# then show its results. (Until the server lands, the job runs through foam-run directly.)
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/build.sh release
out="out/demo-doublet"
rm -rf "$out"
echo "== foam-run examples/doublet.toml --out $out"
./build/release/runner/foam-run examples/doublet.toml --out "$out"
echo
echo "== samples ($out/samples.csv)"
column -s, -t < "$out/samples.csv"
echo
echo "== summary ($out/summary.json)"
cat "$out/summary.json"
echo
