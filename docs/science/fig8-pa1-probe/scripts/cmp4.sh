#!/bin/bash
# p_a r/2γ 1, α 0.4375, seed 2: the volume guard raised to 0.2, 1 s with the bound, 900 s, samples every 5 s
mkdir -p "${OUT:-/tmp/fig8-pa1-probe}"
cd "$(dirname "$0")/../../../.."
OMP_NUM_THREADS=1 build/release/runner/foam-run studies/specs/fusion-2x20.toml --out ${OUT:-/tmp/fig8-pa1-probe}/cmp-vol02-s2 --force \
    --set seed=2 --set duration_s=900 --set snapshot_every_s=0 --set sample_every_s=5 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=1 \
    --set numerics.cg_tol=0.01 --set cells.pa_reduced=1 --set cells.alpha=0.4375 --set cells.l_eta_reduced=0.5 \
    --set numerics.contact_within_prisms=true --set numerics.contact_prisms_overlap_only=true \
    --set numerics.max_volume_error=0.2 \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet > ${OUT:-/tmp/fig8-pa1-probe}/cmp-vol02-s2.log 2>&1
# the same 60 s at the studies' step (the law at 0.25 s / 1e-3)
OMP_NUM_THREADS=1 build/release/runner/foam-run studies/specs/fusion-2x20.toml --out ${OUT:-/tmp/fig8-pa1-probe}/cmp-vol02-s2-law025 --force \
    --set seed=2 --set duration_s=60 --set snapshot_every_s=0 --set sample_every_s=5 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=0.25 \
    --set numerics.cg_tol=0.001 --set cells.pa_reduced=1 --set cells.alpha=0.4375 --set cells.l_eta_reduced=0.5 \
    --set numerics.max_volume_error=0.2 \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet
