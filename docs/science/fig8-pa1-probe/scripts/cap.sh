#!/bin/bash
# step.sh's runs (p_a r/2γ = 1, α 0.4375, Δt 0.5 s / ε_CG 1e-2, the bound, the prepared polarities,
# the rescue, guard 20 %, 1 h) with the contact pressure capped at 0.3 µm; seeds as arguments.
#   OUT=/tmp/fig8-pa1-probe docs/science/fig8-pa1-probe/scripts/cap.sh 1 2 3
mkdir -p "${OUT:-/tmp/fig8-pa1-probe}"
cd "$(dirname "$0")/../../../.."
for s in "$@"; do
  OMP_NUM_THREADS=1 build/release/runner/foam-run studies/specs/fusion-2x20.toml --out ${OUT:-/tmp/fig8-pa1-probe}/cap03-s$s --force \
    --set seed=$s --set duration_s=3600 --set snapshot_every_s=0 --set sample_every_s=10 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=0.5 \
    --set numerics.cg_tol=0.01 --set cells.pa_reduced=1 --set cells.alpha=0.4375 --set cells.l_eta_reduced=0.5 \
    --set numerics.contact_within_prisms=true --set numerics.contact_prisms_overlap_only=true \
    --set scene.polarity_from_preparation=true --set numerics.remesh_rescue=true \
    --set numerics.max_volume_error=0.2 --set numerics.contact_max_overlap_um=0.3 \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet > ${OUT:-/tmp/fig8-pa1-probe}/cap03-s$s.log 2>&1 &
done
wait
