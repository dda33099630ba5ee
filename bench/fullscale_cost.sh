#!/usr/bin/env bash
# What a full-scale study costs: one 2 × 100-cell fusion job from the touching spheroids
# at the full-scale study files' step and at the reduced figure studies' step, per step and per
# simulated hour, (a) as one job on T threads pinned to cores 0 … T−1 and (b) as P one-thread jobs
# side by side on cores 0 … P−1 — the layout of a node running a study (foamd's default: one
# thread a job). Prints one CSV row per run; every run of a configuration must give the same
# samples (wall time aside): the engine's same bits for any thread count.
#
#   bench/fullscale_cost.sh FOAM_RUN CACHE OUT ["1 2 4 8 16"] [P] [STEPS] [REPS]
#
# full:   the full-scale study files' step at the supplement's nominal point: the `reference`
#         preset (contact-implicit-consistent, Δt 0.25 s, ε_CG 1e-3, the supplement's contact
#         law) with the keep-out at 1 µm, as every full-scale file runs it;
# figure: the reduced figure studies' step, the `standard` preset (Δt 1 s, ε_CG 1e-2, the
#         contact's overlap within prisms), at fig8-reduced's base point on the same 2 × 100
#         scene — step fitness passed it at 2 × 20; at 2 × 100 it is
#         studies/step-fitness-full.toml's question.
# Both with the remesh repairs, the volume guard at 20 % and the prepared polarities.
# STEPS (default 60) steps each, timed from the first sample to the last (setup excluded); P
# (default: the threads list's largest) jobs side by side; REPS (default 2) repetitions of (a).
# CACHE: prepared spheroids (foam-run --spheroid-cache); each configuration prepares its two on
# first use, untimed (~4 min of one core each pair).
set -euo pipefail
if [ $# -lt 3 ]; then
  sed -n 2,22p "$0" >&2
  exit 2
fi
foam_run=$1 cache=$2 out=$3 threads=${4:-1 2 4 8 16}
p=${5:-$(tr ' ' '\n' <<<"$threads" | sort -n | tail -1)} steps=${6:-60} reps=${7:-2}
root="$(cd "$(dirname "$0")/.." && pwd)"
spec="$root/studies/specs/fusion-2x100.toml"
common=(--set seed=1 --set snapshot_every_s=0 --set scene.polarity_from_preparation=true
        --set numerics.remesh_repair=rescue-rebuild --set numerics.max_volume_error=0.2
        --set numerics.remesh_keep_out_um=1.0)
# shellcheck disable=SC2034  # used through run_one's nameref
full=(--set numerics.preset=reference)
# shellcheck disable=SC2034
figure=(--set numerics.preset=standard --set cells.pa_reduced=0.33 --set cells.l_eta_reduced=0.5)
dt_of() { [ "$1" = full ] && echo 0.25 || echo 1; }
mkdir -p "$out"
{ nproc; lscpu; uptime; } >"$out/host.txt" 2>&1
run_one() {  # DIR CONFIG THREADS CORES
  local dt duration sample
  dt=$(dt_of "$2")
  duration=$(awk -v s="$steps" -v d="$dt" 'BEGIN { print s * d }')
  sample=$(awk -v s="$steps" -v d="$dt" 'BEGIN { print s * d / 4 }')
  local -n extra=$2
  rm -rf "$1"
  taskset -c "$4" "$foam_run" "$spec" --out "$1" --spheroid-cache "$cache" --threads "$3" -q \
    --checkpoint-every 0 "${common[@]}" "${extra[@]}" --set duration_s="$duration" \
    --set sample_every_s="$sample" >"$1.log" 2>&1
}
samples_key() { cut -d, -f1,2,4- "$1/samples.csv" | md5sum | cut -d' ' -f1; }
# ms per step from the first sample (after step 0's setup) to the last; mean CG iterations.
cost() {
  awk -F, 'NR == 2 { w0 = $3; s0 = $2 } NR > 1 { w = $3; s = $2; cg += $4; n++ }
    END { printf "%.1f,%.1f", 1000 * (w - w0) / (s - s0), cg / n }' "$1/samples.csv"
}
echo "config,layout,threads,concurrent,rep,steps,ms_per_step,cg_iters_mean,core_h_per_sim_h,same_bits"
row() {  # DIR CONFIG LAYOUT THREADS CONCURRENT REP FIRST_KEY
  local c ms
  c=$(cost "$1")
  ms=${c%,*}
  awk -v cfg="$2" -v l="$3" -v t="$4" -v p="$5" -v r="$6" -v n="$steps" -v c="$c" -v ms="$ms" \
    -v dt="$(dt_of "$2")" -v same="$([ "$(samples_key "$1")" = "$7" ] && echo yes || echo no)" \
    'BEGIN { printf "%s,%s,%s,%s,%s,%s,%s,%.2f,%s\n", cfg, l, t, p, r, n, c,
             t * ms / 1000 / dt, same }'
}
for config in full figure; do
  run_one "$out/$config-prepare" "$config" 1 0  # prepares (or loads) its spheroids, untimed
  key=$(samples_key "$out/$config-prepare")
  for rep in $(seq 1 "$reps"); do
    for t in $threads; do
      d="$out/$config-t$t-r$rep"
      run_one "$d" "$config" "$t" "0-$((t - 1))"
      row "$d" "$config" one-job "$t" 1 "$rep" "$key"
    done
  done
  for k in $(seq 0 $((p - 1))); do
    run_one "$out/$config-side-c$k" "$config" 1 "$k" &
  done
  wait
  for k in $(seq 0 $((p - 1))); do
    row "$out/$config-side-c$k" "$config" side-by-side 1 "$p" 1 "$key"
  done
done
uptime >>"$out/host.txt"
