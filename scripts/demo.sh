#!/usr/bin/env bash
# The main job of the README: install, build, start foamd on a fresh database, submit a small job
# with foam, watch it to the end, print its results, stop foamd.
# The job is a small fusion (examples/fusion.toml): θ(t) per sample, θ_eq and τ_f from the fits.
set -euo pipefail
cd "$(dirname "$0")/.."
# DEMO_SKIP_BUILD=1 DEMO_BUILD_DIR=DIR: use an existing build (the ctest that runs this script).
[ -n "${DEMO_SKIP_BUILD:-}" ] || ./scripts/build.sh release
bin="${DEMO_BUILD_DIR:-build/release}"
work="$(mktemp -d)"
port="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')"
echo "== foamd --listen 127.0.0.1:$port --db $work/foamd.db   (log: $work/foamd.log)"
"$bin/server/foamd" --listen "127.0.0.1:$port" --db "$work/foamd.db" --workers 1 \
  >"$work/foamd.log" 2>&1 &
foamd_pid=$!
trap 'kill -TERM $foamd_pid 2>/dev/null || true; wait $foamd_pid 2>/dev/null || true' EXIT
export FOAM_SERVER="127.0.0.1:$port"
for _ in $(seq 50); do "$bin/client/foam" list >/dev/null 2>&1 && break; sleep 0.1; done
echo "== foam submit examples/fusion.toml --wait"
id="$("$bin/client/foam" submit examples/fusion.toml --wait | head -1)"
echo
echo "== foam show $id"
"$bin/client/foam" show "$id"
echo
echo "== foam results $id"
"$bin/client/foam" results "$id"
echo
echo "== foam results $id --csv (samples)"
"$bin/client/foam" results "$id" --csv | column -s, -t
