#!/usr/bin/env bash
# What each preset costs a simulated hour on the reduced (2 × 20 cells) and the full-scale
# (2 × 100) fusion, one thread, measured in one run on one host: the fusion's first minutes from
# the touching spheroids (the dearest part of a day: CG iterations fall as the junctions settle).
# Prints one CSV row per run.
#
#   bench/preset_cost.sh FOAM_RUN CACHE OUT [MINUTES_2x20] [MINUTES_2x100]
#
# CACHE: prepared spheroids (foam-run --spheroid-cache); both presets start from the same ones
# (the preparation does not depend on the preset), prepared on first use, untimed (~30 s a pair
# at 2 × 20, ~4 min at 2 × 100).
set -euo pipefail
if [ $# -lt 3 ]; then
  sed -n 2,12p "$0" >&2
  exit 2
fi
foam_run=$1 cache=$2 out=$3 m20=${4:-10} m100=${5:-2}
root="$(cd "$(dirname "$0")/.." && pwd)"
mkdir -p "$out"
{ nproc; lscpu | grep -E 'Model name|MHz'; uptime; } >"$out/host.txt" 2>&1
dt_of() { [ "$1" = standard ] && echo 1 || echo 0.25; }
echo "scene,preset,dt_s,minutes,steps,ms_per_step,cg_iters_mean,wall_min_per_sim_h"
for scene in 2x20 2x100; do
  minutes=$m20
  [ "$scene" = 2x100 ] && minutes=$m100
  for preset in standard reference; do
    d="$out/$scene-$preset"
    rm -rf "$d"
    duration=$((minutes * 60))
    OMP_NUM_THREADS=1 "$foam_run" "$root/studies/specs/fusion-$scene.toml" --out "$d" \
      --spheroid-cache "$cache" --threads 1 -q --checkpoint-every 0 \
      --set seed=1 --set snapshot_every_s=0 --set cells.pa_reduced=0.33 \
      --set cells.l_eta_reduced=0.5 --set numerics.preset="$preset" \
      --set duration_s="$duration" --set sample_every_s=$((duration / 4)) >"$d.log" 2>&1
    # Timed from the first sample (after step 0's setup and the preparation) to the last.
    awk -F, -v sc="$scene" -v p="$preset" -v dt="$(dt_of "$preset")" -v m="$minutes" '
      NR == 2 { w0 = $3; s0 = $2 } NR > 1 { w = $3; s = $2; cg += $4; n++ }
      END { ms = 1000 * (w - w0) / (s - s0)
            printf "%s,%s,%s,%s,%d,%.1f,%.1f,%.1f\n", sc, p, dt, m, s - s0, ms, cg / n,
                   ms / 1000 / dt * 3600 / 60 }' "$d/samples.csv"
  done
done
uptime >>"$out/host.txt"
