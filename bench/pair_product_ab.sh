#!/usr/bin/env bash
# Two builds of foam-run, interleaved in one run on one host, at the studies' step
# (contact-implicit-consistent, Δt 0.5 s, block-Jacobi, ε_CG 1e-2): 2 × 100 on one and two
# threads (30 steps), 2 × 20 on one (60 steps), REPS repetitions, pinned to cores 0 (and 1).
#   bench/pair_product_ab.sh OLD_FOAM_RUN NEW_FOAM_RUN CACHE OUT [REPS]
# Scenes and CACHE as bench/thread_scaling.sh's. Writes OUT/rows.md: bench/step_cost.py's table
# of the runs (CG iterations, ms a step, its phases).
set -uo pipefail
if [ $# -lt 4 ]; then
  sed -n 2,7p "$0" >&2
  exit 2
fi
old=$1 new=$2 cache=$3 out=$4 reps=${5:-5}
root="$(cd "$(dirname "$0")/.." && pwd)"
spec100=$root/bench/specs/fusion_reference.toml spec20=$root/bench/specs/fusion_reference_2x20.toml
config=(--set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=0.5
        --set numerics.preconditioner=block-jacobi --set numerics.cg_tol=0.01)
mkdir -p "$out"
run() {  # build threads cpus spec steps name
  local bin=$old duration
  [ "$1" = new ] && bin=$new
  duration=$(awk -v s="$5" 'BEGIN { print s * 0.5 }')
  OMP_NUM_THREADS=$2 taskset -c "$3" "$bin" "$4" --out "$out/$6" --force \
    --spheroid-cache "$cache" --threads "$2" -q --checkpoint-every 0 \
    --set duration_s="$duration" --set sample_every_s="$duration" --set snapshot_every_s=0 \
    "${config[@]}" > "$out/$6.log" 2>&1
}
# Each build prepares (or loads) its spheroids first, untimed: the cache key holds the engine's
# version and every key, so two builds share them only where those agree.
for b in old new; do
  run $b 1 0 "$spec100" 1 "prepare-n100-$b"
  run $b 1 0 "$spec20" 1 "prepare-n20-$b"
done
for rep in $(seq "$reps"); do
  for b in old new; do
    run $b 1 0 "$spec100" 30 "n100-t1-$b-r$rep"
    run $b 1 0 "$spec20" 60 "n20-t1-$b-r$rep"
    run $b 2 0-1 "$spec100" 30 "n100-t2-$b-r$rep"
  done
done
# shellcheck disable=SC2046  # one argument a folder; the names hold no spaces
"$root/bench/step_cost.py" table $(find "$out" -mindepth 1 -maxdepth 1 -type d -name 'n*' | sort -V) \
  > "$out/rows.md"
echo "rows: $out/rows.md"
