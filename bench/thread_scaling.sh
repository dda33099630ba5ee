#!/usr/bin/env bash
# One job's threads: the cost per step of the studies' step (contact-implicit-consistent,
# Δt 0.5 s, block-Jacobi, ε_CG 1e-2) on the fused 2 × 100 and 2 × 20 scenes
# (bench/specs/fusion_reference.toml, bench/specs/fusion_reference_2x20.toml) at T threads pinned
# to cores 0 … T−1, and the same job as two one-thread processes side by side on cores 0 and 1 (a
# sweep's layout), REPS repetitions: 30 steps of the 2 × 100, 60 of the 2 × 20, whose rows stop at
# 4 threads (a 2 × 20 step is too small for more). One foam-run folder a run under OUT (NAME.time:
# wall, user, system seconds of the process), and OUT/rows.md: bench/step_cost.py's table of them.
#
#   bench/thread_scaling.sh FOAM_RUN CACHE OUT ["1 2 4 8 16"] [REPS]
#
# CACHE: prepared spheroids (foam-run --spheroid-cache); a first run of each scene prepares them
# on a miss, untimed (~4 min of one core at 2 × 100).
set -uo pipefail
if [ $# -lt 3 ]; then
  sed -n 2,13p "$0" >&2
  exit 2
fi
foam_run=$1 cache=$2 out=$3 threads=${4:-1 2 4 8 16} reps=${5:-3}
root="$(cd "$(dirname "$0")/.." && pwd)"
spec100=$root/bench/specs/fusion_reference.toml spec20=$root/bench/specs/fusion_reference_2x20.toml
config=(--set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=0.5
        --set numerics.preconditioner=block-jacobi --set numerics.cg_tol=0.01)
mkdir -p "$out"
{ nproc; lscpu; uptime; } > "$out/host.txt" 2>&1
TIMEFORMAT='%R %U %S'
run() {  # name threads cpus spec steps [timeout]
  local duration
  duration=$(awk -v s="$5" 'BEGIN { print s * 0.5 }')
  { time OMP_NUM_THREADS=$2 taskset -c "$3" timeout "${6:-300}" "$foam_run" "$4" --out "$out/$1" \
      --force --spheroid-cache "$cache" --threads "$2" -q --checkpoint-every 0 \
      --set duration_s="$duration" --set sample_every_s="$duration" --set snapshot_every_s=0 \
      "${config[@]}" > "$out/$1.log" 2>&1; } 2> "$out/$1.time"
}
run prepare-n100 1 0 "$spec100" 1 3600
run prepare-n20 1 0 "$spec20" 1 3600
for rep in $(seq "$reps"); do
  for t in $threads; do
    run "n100-t$t-r$rep" "$t" "0-$((t - 1))" "$spec100" 30
    [ "$t" -le 4 ] && run "n20-t$t-r$rep" "$t" "0-$((t - 1))" "$spec20" 60
  done
  run "n100-pairA-r$rep" 1 0 "$spec100" 30 & run "n100-pairB-r$rep" 1 1 "$spec100" 30 &
  wait
  run "n20-pairA-r$rep" 1 0 "$spec20" 60 & run "n20-pairB-r$rep" 1 1 "$spec20" 60 &
  wait
done
uptime >> "$out/host.txt"
# shellcheck disable=SC2046  # one argument a folder; the names hold no spaces
"$root/bench/step_cost.py" table $(find "$out" -mindepth 1 -maxdepth 1 -type d -name 'n*' | sort -V) \
  > "$out/rows.md"
echo "rows: $out/rows.md"
