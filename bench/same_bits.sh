#!/usr/bin/env bash
# Hashes of the runs that a change to the step must leave bit-identical:
#   ref-T     the reference fusion (2 × 100 cells, bench/specs/fusion_reference.toml: the
#             one-spring contact-implicit step at Δt 0.5 s), 24 steps, samples every second, at
#             T = 1, 2, 3 threads (the spheroids come from the cache given, so their preparation
#             is compared only by the next run)
#   ci300     a 2 × 20 fusion at the one-spring contact-implicit step (Δt 0.5 s, ε_CG 1e-2, the
#             supplement's contact law), 300 s, spheroids prepared in the run
#   ros2      a 2 × 20 fusion with the ros2 integrator (adaptive, error-controlled: ~40 % of its
#             tries are rejected), 20 s
#   ros2-dbl  the doublet with ros2, 300 s
# Each line: name, then the SHA-256 of samples.csv without its wall_s column (wall time is not a
# result). Further arguments name the runs to do (default: all). Compare two engines line by line:
#   bench/same_bits.sh OLD/foam-run /tmp/old > old.txt
#   bench/same_bits.sh build/release/runner/foam-run /tmp/new > new.txt && diff old.txt new.txt
set -euo pipefail
bin=${1:?usage: same_bits.sh FOAM_RUN WORKDIR}
work=${2:?usage: same_bits.sh FOAM_RUN WORKDIR}
root="$(cd "$(dirname "$0")/.." && pwd)"
mkdir -p "$work"
cache="$work/cache"
shift 2
only=" $* "

# samples.csv without wall_s, hashed
hash() {
  /usr/bin/python3 - "$1/samples.csv" <<'EOF'
import csv, hashlib, sys
rows = list(csv.reader(open(sys.argv[1])))
keep = [i for i, name in enumerate(rows[0]) if name != "wall_s"]
text = "\n".join(",".join(r[i] for i in keep) for r in rows)
print(hashlib.sha256(text.encode()).hexdigest())
EOF
}

run() {  # name, spec, then foam-run arguments
  local name=$1 spec=$2
  shift 2
  [ "$only" = "  " ] || [[ "$only" == *" $name "* ]] || return 0
  "$bin" "$spec" --out "$work/$name" --force --quiet "$@" >/dev/null ||
    { echo "same_bits.sh: $name failed (see $work/$name/summary.json)" >&2; exit 1; }
  echo "$name $(hash "$work/$name")"
}

for t in 1 2 3; do
  run "ref-$t" "$root/bench/specs/fusion_reference.toml" --set duration_s=12 \
    --set sample_every_s=1 --threads "$t" --spheroid-cache "$cache"
done
run ci300 "$root/studies/specs/fusion-2x20.toml" --set numerics.integrator=contact-implicit \
  --set numerics.dt_s=0.5 --set numerics.cg_tol=0.01 --set numerics.contact_law=supplement \
  --set duration_s=300 --set sample_every_s=10 --set snapshot_every_s=0 --no-cache --threads 2
run ros2 "$root/studies/specs/fusion-2x20.toml" --set numerics.integrator=ros2 \
  --set numerics.dt_s=0.5 --set numerics.adaptive=true --set numerics.max_step_error_um=0.05 \
  --set duration_s=20 --set sample_every_s=2 --set snapshot_every_s=0 \
  --spheroid-cache "$cache" --threads 2
run ros2-dbl "$root/examples/doublet.toml" --set numerics.integrator=ros2 \
  --set numerics.dt_s=0.5 --set duration_s=300 --set sample_every_s=10 --set snapshot_every_s=0 \
  --threads 2
