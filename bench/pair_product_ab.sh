#!/usr/bin/env bash
# Two builds of bench/study_fusion_cost, interleaved in one run on one host, at the studies' step
# (contact-implicit-consistent, Δt 0.5 s, block-Jacobi, ε_CG 1e-2): 2 × 100 on one and two
# threads (30 steps), 2 × 20 on one (60 steps), REPS repetitions, pinned to cores 0 (and 1).
#   bench/pair_product_ab.sh OLD_STUDY_FUSION_COST NEW_STUDY_FUSION_COST CACHE100 CACHE20 OUT [REPS]
# CACHE100 / CACHE20 as bench/thread_scaling.sh's. Writes OUT/rows.txt: name, CG iterations per
# step, ms per step, solve (ms).
set -uo pipefail
if [ $# -lt 5 ]; then
  sed -n 2,7p "$0" >&2
  exit 2
fi
old=$1 new=$2 c100=$3 c20=$4 out=$5 reps=${6:-5}
config=contact-implicit-consistent:0.5:block-jacobi:1e-2
mkdir -p "$out"
run() {  # build threads cpus cache steps n prep name
  local bin=$old
  [ "$1" = new ] && bin=$new
  OMP_NUM_THREADS=$2 taskset -c "$3" "$bin" "$4" "$5" "$6" "$7" "$config" 2>/dev/null | tail -1 \
    > "$out/$8.md"
}
for rep in $(seq "$reps"); do
  for b in old new; do
    run $b 1 0 "$c100" 30 100 600 "n100-t1-$b-r$rep"
    run $b 1 0 "$c20" 60 20 1800 "n20-t1-$b-r$rep"
    run $b 2 0-1 "$c100" 30 100 600 "n100-t2-$b-r$rep"
  done
done
for f in "$out"/n*.md; do
  printf '%s %s\n' "$(basename "$f" .md)" "$(awk -F'|' '{print $6, $7, $12}' "$f")"
done | sort -V > "$out/rows.txt"
echo "rows: $out/rows.txt"
