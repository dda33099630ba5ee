#!/bin/bash
mkdir -p "${OUT:-/tmp/fig8-pa1-probe}"
cd "$(dirname "$0")/../../../.."
for s in "$@"; do
  OMP_NUM_THREADS=1 /usr/bin/time -f '%U %e' -o ${OUT:-/tmp/fig8-pa1-probe}/time-$s.txt build/release/runner/foam-run \
    studies/specs/fusion-2x20.toml --out ${OUT:-/tmp/fig8-pa1-probe}/seed$s --resume \
    --set seed=$s --set duration_s=21600 --set snapshot_every_s=3600 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=1 \
    --set numerics.cg_tol=0.01 --set cells.pa_reduced=1 --set cells.alpha=0.3 --set cells.l_eta_reduced=0.5 \
    --set numerics.contact_within_prisms=true --set numerics.contact_prisms_overlap_only=true \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet > ${OUT:-/tmp/fig8-pa1-probe}/log-$s.txt 2>&1
done
