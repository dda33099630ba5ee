#!/usr/bin/env bash
# Sweep throughput on a node: a sweep of JOBS equal fusion jobs on CORES cores,
# run as P concurrent foam-run processes of T threads each (P × T ≤ CORES, waves of P until JOBS
# are done), for each layout given. Prints one CSV row per layout and repetition: the sweep's wall
# time and its throughput in jobs per hour, and whether every job's samples (wall time aside)
# equal the first job's — the engine promises the same bits for any thread count.
#
#   bench/sweep_throughput.sh FOAM_RUN CACHE OUT CORES "1x2 2x1" [JOBS] [DURATION_S] [REPS]
#
# The job: the reduced base point (studies/specs/fusion-2x20.toml, seed 1) at the studies'
# candidate step (contact-implicit-consistent, Δt 1 s, ε_CG 1e-2), DURATION_S simulated seconds
# (default 300) from the spheroids in CACHE (foam-run --spheroid-cache; prepared once if absent).
# The layouts are pinned to cores 0 … CORES−1 (taskset), so a larger machine can measure a
# smaller node without the rest of it.
set -euo pipefail
if [ $# -lt 5 ]; then
  sed -n 2,16p "$0" >&2
  exit 2
fi
foam_run=$1 cache=$2 out=$3 cores=$4 layouts=$5
jobs=${6:-4} duration=${7:-300} reps=${8:-2}
spec="$(cd "$(dirname "$0")/.." && pwd)/studies/specs/fusion-2x20.toml"
mkdir -p "$out"
run_one() {  # DIR THREADS
  OMP_NUM_THREADS=$2 "$foam_run" "$spec" --out "$1" --spheroid-cache "$cache" --threads "$2" \
    --set seed=1 --set duration_s="$duration" --set sample_every_s=60 --set snapshot_every_s=0 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=1 \
    --set numerics.cg_tol=0.01 >"$1.log" 2>&1
}
# Samples without the wall-time column, for the same-bits check.
samples_key() { cut -d, -f1,2,4- "$1/samples.csv" | md5sum | cut -d' ' -f1; }
# Prepare (or load) the spheroids once, outside the timed sweeps.
run_one "$out/prepare" 1
first=$(samples_key "$out/prepare")
echo "cores,concurrent,threads_each,jobs,rep,wall_s,jobs_per_hour,same_bits"
for rep in $(seq 1 "$reps"); do
  for layout in $layouts; do
    p=${layout%x*} t=${layout#*x}
    if [ $((p * t)) -gt "$cores" ]; then
      echo "sweep_throughput.sh: layout $layout needs $((p * t)) cores, more than $cores" >&2
      exit 2
    fi
    dir="$out/$layout-rep$rep"
    rm -rf "$dir"
    mkdir -p "$dir"
    start=$(date +%s.%N)
    done_jobs=0
    while [ "$done_jobs" -lt "$jobs" ]; do
      pids=()
      for k in $(seq 0 $((p - 1))); do
        [ "$done_jobs" -lt "$jobs" ] || break
        first_core=$((k * t))
        taskset -c "$first_core-$((first_core + t - 1))" bash -c "$(declare -f run_one); \
          foam_run='$foam_run' spec='$spec' cache='$cache' duration='$duration' \
          run_one '$dir/job$done_jobs' $t" &
        pids+=($!)
        done_jobs=$((done_jobs + 1))
      done
      for pid in "${pids[@]}"; do wait "$pid"; done
    done
    wall=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN { print b - a }')
    same=yes
    for j in $(seq 0 $((jobs - 1))); do
      [ "$(samples_key "$dir/job$j")" = "$first" ] || same=no
    done
    awk -v c="$cores" -v p="$p" -v t="$t" -v j="$jobs" -v r="$rep" -v w="$wall" -v s="$same" \
      'BEGIN { printf "%s,%s,%s,%s,%s,%.1f,%.1f,%s\n", c, p, t, j, r, w, 3600 * j / w, s }'
  done
done
