#!/bin/bash
# CPU seconds for the first DURATION simulated seconds of the reduced fusion study's scene
# (2 × 30 cells, seed 1, the study's settings and prepared spheroids), one foam-run at a time on
# one thread, per configuration "integrator dt preconditioner" (docs/benchmarks.md,
# "8. CG iterations"; docs/study/fusion-ros2.md).
#
#   bench/fusion_cpu_cost.sh FOAM_RUN CACHE_DIR OUT_DIR [DURATION ≥ 30] ["integrator dt pre" ...]
# CACHE_DIR: the study's spheroid cache (docs/study/fusion_accuracy.py DIR fills DIR/cache).
set -euo pipefail
fr=$1 cache=$2 out=$3 duration=${4:-120}
shift $(( $# < 4 ? $# : 4 ))
configs=("$@")
[ ${#configs[@]} -gt 0 ] || configs=("contact-implicit 0.1 jacobi" "contact-implicit 0.1 incomplete-cholesky"
  "contact-implicit 0.5 jacobi" "contact-implicit 0.5 incomplete-cholesky"
  "contact-implicit 1 incomplete-cholesky" "ros2 0.5 jacobi" "ros2 0.5 incomplete-cholesky"
  "ros2 1 incomplete-cholesky")
mkdir -p "$out"
for cfg in "${configs[@]}"; do
  set -- $cfg
  run="$out/$1-$2-$3"
  rm -rf "$run"
  /usr/bin/time -f "%U %S %e" -o "$run.time" env OMP_NUM_THREADS=1 "$fr" - --out "$run" \
    --spheroid-cache "$cache" -q --set seed=1 --set sample_every_s=30 --set snapshot_every_s=0 \
    --set scene.prep_max_s=600 --set numerics.integrator=\"$1\" --set numerics.dt_s=$2 \
    --set numerics.cg_tol=0.001 --set numerics.triangles_per_cell=320 \
    --set numerics.preconditioner=\"$3\" --set numerics.contact_quadrature=\"exact\" \
    --set duration_s=$duration --set scene.n_cells=30 <<< 'scene = "fusion"'
  read -r user sys wall < "$run.time"
  echo "$1 $2 $3: CPU ${user} s user + ${sys} s sys, wall ${wall} s, CG iterations per step" \
    "$(tail -1 "$run/samples.csv" | cut -d, -f4)"
done
