#!/usr/bin/env bash
# One job's threads: the cost per step of the studies' step (contact-implicit-consistent,
# Δt 0.5 s, block-Jacobi, ε_CG 1e-2) on the fused 2 × 100 and 2 × 20 scenes at T threads pinned to
# cores 0 … T−1, and the same job as two one-thread processes side by side on cores 0 and 1 (a
# sweep's layout), REPS repetitions. One markdown row per run under OUT (NAME.md: the row of
# bench/study_fusion_cost; NAME.time: wall, user, system seconds).
#
#   bench/thread_scaling.sh STUDY_FUSION_COST CACHE100 CACHE20 OUT ["1 2 4 8 16"] [REPS]
#
# CACHE100: the spheroids of bench/specs/fusion_reference.toml (prep_max_s 600); CACHE20 those of
# studies/specs/fusion-2x20.toml (prep_max_s 1800), as foam-run --spheroid-cache leaves them.
# The 2 × 20 rows stop at 4 threads (a 2 × 20 step is too small for more).
set -uo pipefail
if [ $# -lt 4 ]; then
  sed -n 2,13p "$0" >&2
  exit 2
fi
bin=$1 c100=$2 c20=$3 out=$4 threads=${5:-1 2 4 8 16} reps=${6:-3}
config=contact-implicit-consistent:0.5:block-jacobi:1e-2
mkdir -p "$out"
{ nproc; lscpu; uptime; } > "$out/host.txt" 2>&1
TIMEFORMAT='%R %U %S'
run() {  # name threads cpus n steps prep cache
  { time OMP_NUM_THREADS=$2 taskset -c "$3" timeout 300 "$bin" "$7" "$5" "$4" "$6" "$config" \
      > "$out/$1.md" 2> "$out/$1.err"; } 2> "$out/$1.time"
}
for rep in $(seq "$reps"); do
  for t in $threads; do
    run "n100-t$t-r$rep" "$t" "0-$((t - 1))" 100 30 600 "$c100"
    [ "$t" -le 4 ] && run "n20-t$t-r$rep" "$t" "0-$((t - 1))" 20 60 1800 "$c20"
  done
  run "n100-pairA-r$rep" 1 0 100 30 600 "$c100" & run "n100-pairB-r$rep" 1 1 100 30 600 "$c100" &
  wait
  run "n20-pairA-r$rep" 1 0 20 60 1800 "$c20" & run "n20-pairB-r$rep" 1 1 20 60 1800 "$c20" &
  wait
done
uptime >> "$out/host.txt"
# The table: name, CG iterations per step, ms per step and its phases.
for f in "$out"/n*.md; do
  printf '%s %s\n' "$(basename "$f" .md)" "$(tail -1 "$f" | awk -F'|' '{print $6, $7, $9, $11, $12, $13}')"
done | sort -V > "$out/rows.txt"
echo "rows: $out/rows.txt (name, CG iterations, ms/step, contacts, matrix, solve, remesh)"
