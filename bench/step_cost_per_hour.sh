#!/usr/bin/env bash
# CPU seconds per simulated hour of one spec under several numerics, measured in one run on one
# host: foam-run over the spec's first DURATION simulated seconds (one thread), every
# configuration once per repetition, the configurations interleaved so that the host's drift
# falls on all alike; with two cores free, two repetitions at once, pinned to cores 0 and 1.
#   bench/step_cost_per_hour.sh FOAM_RUN SPEC CACHE OUT DURATION REPS 'NAME|--set K=V ...' ...
# SPEC: a spec file (JSON or TOML) — for a stored job, `foam show --json ID` gives spec_json;
# CACHE: the spheroid cache the spec's fusion reads (so that only the fusion is timed).
# Writes OUT/rows.csv (name, rep, cpu_s, wall_s, steps, cg_iters_mean, t_s) and prints, per
# configuration, the median CPU per simulated hour and its ratio to the first configuration.
set -euo pipefail
if [ $# -lt 7 ]; then
  sed -n 2,10p "$0" >&2
  exit 2
fi
fr=$1 spec=$2 cache=$3 out=$4 duration=$5 reps=$6
shift 6
mkdir -p "$out"
echo "name,rep,cpu_s,wall_s,steps,cg_iters_mean,t_s" >"$out/rows.csv"
one() {  # rep cpu name sets...
  local rep=$1 cpu=$2 name=$3
  shift 3
  local dir="$out/${name//[^A-Za-z0-9.]/_}-r$rep"
  rm -rf "$dir"
  # shellcheck disable=SC2068
  /usr/bin/time -f "%U %S %e" -o "$dir.time" env OMP_NUM_THREADS=1 taskset -c "$cpu" \
    "$fr" "$spec" --out "$dir" --spheroid-cache "$cache" --threads 1 -q \
    --set duration_s="$duration" --set snapshot_every_s=0 $@
  read -r user sys wall <"$dir.time"
  # samples.csv: t_s, steps, wall_s, cg_iters_mean, ... (the last sample is the run's end).
  local last
  last=$(tail -1 "$dir/samples.csv")
  echo "$name,$rep,$(echo "$user + $sys" | bc),$wall,$(echo "$last" | cut -d, -f2),$(echo "$last" | cut -d, -f4),$(echo "$last" | cut -d, -f1)" \
    >>"$out/rows.csv"
}
cores=$(nproc)
rep=1
while [ "$rep" -le "$reps" ]; do
  for cfg in "$@"; do
    name=${cfg%%|*}
    sets=${cfg#*|}
    if [ "$cores" -ge 2 ] && [ $((rep + 1)) -le "$reps" ]; then
      # shellcheck disable=SC2086
      one "$rep" 0 "$name" $sets &
      # shellcheck disable=SC2086
      one $((rep + 1)) 1 "$name" $sets &
      wait
    else
      # shellcheck disable=SC2086
      one "$rep" 0 "$name" $sets
    fi
  done
  [ "$cores" -ge 2 ] && rep=$((rep + 2)) || rep=$((rep + 1))
done
/usr/bin/python3 - "$out/rows.csv" <<'EOF'
import csv, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1])))
names = list(dict.fromkeys(r["name"] for r in rows))
per_h = {n: [float(r["cpu_s"]) / float(r["t_s"]) * 3600 for r in rows if r["name"] == n]
         for n in names}
base = statistics.median(per_h[names[0]])
print(f"{'configuration':<28} {'runs':>4} {'CPU s per sim. hour (median, range)':>38} {'ratio':>7}")
for n in names:
    v = per_h[n]
    m = statistics.median(v)
    print(f"{n:<28} {len(v):>4} {m:>14.0f} ({min(v):.0f}–{max(v):.0f}){'':>12} {base / m:>7.2f}")
EOF
