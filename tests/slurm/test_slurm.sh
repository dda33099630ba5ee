#!/usr/bin/env bash
# The Slurm executor's end-to-end test on a real, single-node Slurm (tests/slurm/slurm-single-node.sh):
# foamd with the Slurm executor runs a sweep as one sbatch array and stores the same results as
# the local pool for the same seeds; a cancelled task ends CANCELLED (scancel), a failing one
# FAILED with its reason; foamd killed mid-sweep and restarted loses nothing.
#
#   tests/slurm/test_slurm.sh [BUILD_DIR]      (default build/release; run as root)
#
# Exit 77 (ctest: skipped) with a line saying why when Slurm cannot run here: not root, or the
# packages are not installed (CI installs them: `tests/slurm/slurm-single-node.sh install`).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=$(cd "${1:-$here/../../build/release}" && pwd)
foamd=$build/server/foamd
foam=$build/client/foam

skip() {
  echo "test_slurm: SKIPPED: $*" >&2
  exit 77
}
[ "$(id -u)" -eq 0 ] || skip "needs root (slurmd, munged)"
for c in slurmctld slurmd sbatch squeue scancel munged; do
  command -v "$c" > /dev/null || skip "$c not installed (tests/slurm/slurm-single-node.sh install)"
done

tmp=$(mktemp -d /tmp/foam-slurm-test.XXXXXX)
state=$tmp/slurm
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done
  "$here/slurm-single-node.sh" stop "$state" > /dev/null 2>&1 || true
  if [ "${KEEP:-0}" = 1 ]; then echo "test_slurm: kept $tmp" >&2; else rm -rf "$tmp"; fi
}
trap cleanup EXIT
fail() {
  echo "test_slurm: FAILED: $*" >&2
  for f in "$tmp"/foamd-*.log; do echo "--- $f" >&2; tail -20 "$f" >&2; done
  exit 1
}

# A machine that cannot host the daemons (no munge socket, a container without the rights) is
# an environment limit, not a defect of foamd: skipped, with the daemons' logs above.
"$here/slurm-single-node.sh" start "$state" || skip "the single-node Slurm did not start here"
# shellcheck disable=SC1091
source "$state/env"
export OMP_NUM_THREADS=1

port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
sport=$(port)
pport=$(port)
head -c 24 /dev/urandom | base64 > "$tmp/token"
chmod 600 "$tmp/token"
start_slurm_foamd() {
  "$foamd" --listen "127.0.0.1:$sport" --db "$tmp/db/foamd.db" --token-file "$tmp/token" \
    --executor slurm --slurm-dir "$tmp/work" --slurm-partition debug --slurm-poll-s 1 \
    --slurm-checkpoint-every-s 2 >> "$tmp/foamd-slurm.log" 2>&1 &
  spid=$!
  pids+=("$spid")
}
start_slurm_foamd
"$foamd" --listen "127.0.0.1:$pport" --db "$tmp/pool/foamd.db" --workers 2 \
  >> "$tmp/foamd-pool.log" 2>&1 &
pids+=($!)
S=("$foam" --server "127.0.0.1:$sport" --token-file "$tmp/token")
P=("$foam" --server "127.0.0.1:$pport")
for _ in $(seq 50); do "${S[@]}" list > /dev/null 2>&1 && "${P[@]}" list > /dev/null 2>&1 && break; sleep 0.2; done

field() { "${@:3}" show "$1" | sed -n "s/^$2: *//p"; }
results_of_sweep() {  # foam CLI..., sweep id → one JSON per line (seed-sorted)
  local sweep=${*: -1}
  local cli=("${@:1:$#-1}")
  for id in $("${cli[@]}" list --sweep "$sweep" | awk 'NR > 1 {print $1}'); do
    "${cli[@]}" results "$id" --json | python3 -c 'import json,sys; print(json.dumps(json.load(sys.stdin)))'
  done
}

echo "== a sweep of 4 jobs as one array, against the local pool" >&2
sweep=(sweep --scene doublet --set duration_s=60 --set sample_every_s=5 --set snapshot_every_s=30
       --set cells.p_a=0 --seeds 1,2,3,4 --wait)
s_sweep=$("${S[@]}" "${sweep[@]}" 2> "$tmp/sweep-s.err") || fail "slurm sweep: $(cat "$tmp/sweep-s.err")"
p_sweep=$("${P[@]}" "${sweep[@]}" 2> /dev/null) || fail "pool sweep failed"
results_of_sweep "${S[@]}" "$s_sweep" > "$tmp/slurm.jsonl"
results_of_sweep "${P[@]}" "$p_sweep" > "$tmp/pool.jsonl"
python3 - "$tmp/slurm.jsonl" "$tmp/pool.jsonl" << 'EOF' || fail "results differ from the local pool's"
import json, sys
def load(path):
    out = {}
    for line in open(path):
        j = json.loads(line)
        out[j["seed"]] = j
    return out
a, b = load(sys.argv[1]), load(sys.argv[2])
assert sorted(a) == [1, 2, 3, 4] and sorted(b) == [1, 2, 3, 4], (sorted(a), sorted(b))
for seed in a:
    x, y = a[seed], b[seed]
    assert x["state"] == y["state"] == "succeeded", (seed, x["state"], y["state"])
    rx = {k: v for k, v in x["results"].items() if k != "wall_s"}
    ry = {k: v for k, v in y["results"].items() if k != "wall_s"}
    assert rx == ry, (seed, rx, ry)
    w = x["columns"].index("wall_s")
    sx = [s[:w] + s[w + 1:] for s in x["samples"]]
    sy = [s[:w] + s[w + 1:] for s in y["samples"]]
    assert sx == sy, seed
    assert x["snapshots"] == y["snapshots"] == 3, (x["snapshots"], y["snapshots"])
print("test_slurm: 4 jobs: results, samples and snapshots equal to the local pool's", file=sys.stderr)
EOF
arrays=$(for id in $("${S[@]}" list --sweep "$s_sweep" | awk 'NR > 1 {print $1}'); do
  field "$id" executor "${S[@]}" | sed 's/_.*//'; done | sort -u | wc -l)
[ "$arrays" = 1 ] || fail "the sweep went to $arrays sbatch calls, not one array"

echo "== cancel a running task" >&2
long=$("${S[@]}" submit --scene doublet --set duration_s=100000 --set sample_every_s=5 \
  --set cells.p_a=0 --set snapshot_every_s=0 2> /dev/null | head -1)
for _ in $(seq 120); do
  ref=$(field "$long" executor "${S[@]}")
  prog=$(field "$long" progress "${S[@]}")
  [ -n "$ref" ] && [ "${prog%% *}" != 0 ] && break
  sleep 0.5
done
[ -n "$ref" ] || fail "the long job never reached Slurm"
"${S[@]}" cancel "$long" > /dev/null
task=${ref#slurm:}
for _ in $(seq 60); do
  st=$(squeue --noheader --array --states=all --format=%T --jobs="${task%_*}" | head -1)
  [ "$st" = CANCELLED ] && break
  sleep 0.5
done
[ "$("${S[@]}" show "$long" | head -1)" = cancelled ] || fail "cancelled job is $("${S[@]}" show "$long" | head -1)"
[ "$st" = CANCELLED ] || fail "Slurm says $st for the cancelled task $task"

echo "== a failing task" >&2
if bad=$("${S[@]}" submit --scene doublet --set duration_s=50 --set sample_every_s=5 \
  --set cells.p_a=0 --set numerics.max_volume_error=1e-9 --wait 2> /dev/null); then
  fail "a run that must fail succeeded"
fi
bad=$(echo "$bad" | head -1)
[ "$("${S[@]}" show "$bad" | head -1)" = failed ] || fail "bad job is not failed"
field "$bad" reason "${S[@]}" | grep -q "volume error" || fail "no reason: $(field "$bad" reason "${S[@]}")"

echo "== a task whose spec is broken on the shared filesystem" >&2
scontrol update PartitionName=debug State=DOWN
inj=$("${S[@]}" submit --scene doublet --set duration_s=50 --set sample_every_s=5 \
  --set cells.p_a=0 2> /dev/null | head -1)
for _ in $(seq 60); do
  [ -n "$(field "$inj" executor "${S[@]}")" ] && break
  sleep 0.5
done
echo 'scene = "nonsense"' > "$tmp/work/jobs/$inj/spec.json"
scontrol update PartitionName=debug State=UP
for _ in $(seq 120); do
  [ "$("${S[@]}" show "$inj" | head -1)" = failed ] && break
  sleep 0.5
done
[ "$("${S[@]}" show "$inj" | head -1)" = failed ] || fail "the injected bad spec did not fail the job"
field "$inj" reason "${S[@]}" | grep -q "invalid spec" ||
  fail "no reason for the bad spec: $(field "$inj" reason "${S[@]}")"

echo "== a task requeued by Slurm, and foamd killed mid-sweep and restarted" >&2
r_sweep=$("${S[@]}" sweep --scene doublet --set duration_s=3000 --set sample_every_s=5 \
  --set snapshot_every_s=1000 --set cells.p_a=0 --seeds 5,6 2> /dev/null)
first=$("${S[@]}" list --sweep "$r_sweep" | awk 'NR > 1 {print $1}' | tail -1)
for _ in $(seq 60); do
  ref=$(field "$first" executor "${S[@]}")
  [ -n "$ref" ] && [ "$(squeue --noheader --array --format=%T --jobs="${ref#slurm:}")" = RUNNING ] && break
  sleep 0.5
done
sleep 3  # a checkpoint or two
scontrol requeue "${ref#slurm:}" || fail "scontrol requeue ${ref#slurm:}"
kill -9 "$spid"
sleep 3
start_slurm_foamd
for _ in $(seq 300); do
  out=$("${S[@]}" list --sweep "$r_sweep" 2> /dev/null) || { sleep 1; continue; }
  echo "$out" | grep -qE "running|queued" || break
  sleep 1
done
results_of_sweep "${S[@]}" "$r_sweep" > "$tmp/restart.jsonl"
python3 - "$tmp/restart.jsonl" << 'EOF' || fail "the restarted sweep lost something"
import json, sys
jobs = [json.loads(line) for line in open(sys.argv[1])]
assert len(jobs) == 2, len(jobs)
for j in jobs:
    assert j["state"] == "succeeded", (j["id"], j["state"], j["reason"])
    assert len(j["samples"]) == 601, len(j["samples"])  # 0, 5, ..., 3000 s: none lost, none twice
    assert [s[0] for s in j["samples"]] == [5.0 * k for k in range(601)]
    assert j["snapshots"] == 4, j["snapshots"]
print("test_slurm: requeue + restart mid-sweep: both jobs complete, 601 samples and 4 "
      "snapshots each", file=sys.stderr)
EOF
echo "test_slurm: PASSED" >&2
