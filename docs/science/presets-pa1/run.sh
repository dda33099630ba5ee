#!/usr/bin/env bash
# fig8's p_a r/2γ = 1 points at the default step (standard: Δt 1 s, adaptive), 2 h each, one
# thread; the committed runs ran Δt 0.5 s (docs/science/fig8-reduced/data).
set -u
root="$(cd "$(dirname "$0")/../../.." && pwd)"
out=${1:?usage: run.sh OUT CACHE}; cache=${2:?usage: run.sh OUT CACHE}
for case in "0.75 1" "0.75 2" "0.75 3" "0.3 1" "0.4375 1"; do
  set -- $case
  a=$1 seed=$2 d=$out/a$1-s$2
  rm -rf "$d"
  OMP_NUM_THREADS=1 "$root/build/release/runner/foam-run" "$root/studies/specs/fusion-2x20.toml" \
    --out "$d" --spheroid-cache "$cache" --threads 1 -q --checkpoint-every 0 \
    --set seed=$seed --set cells.pa_reduced=1 --set cells.alpha=$a --set cells.l_eta_reduced=0.5 \
    --set duration_s=7200 --set sample_every_s=60 > "$d.log" 2>&1
  echo "$a $seed exit $?"
done
