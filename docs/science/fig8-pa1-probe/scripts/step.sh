#!/bin/bash
# A step for the p_a r/2γ = 1 points: α 0.4375, the bound (overlap within prisms), the prepared
# polarities and numerics.remesh_rescue, volume guard 20 %, 1 h, samples every 10 s; Δt 0.5 s /
# ε_CG 1e-2 (seeds 1–3) — compare with guard.sh's Δt 1 s. Two at a time.
#   OUT=/tmp/fig8-pa1-probe docs/science/fig8-pa1-probe/scripts/step.sh
mkdir -p "${OUT:-/tmp/fig8-pa1-probe}"
cd "$(dirname "$0")/../../../.."
run() {
  dt=$1 cg=$2 s=$3
  OMP_NUM_THREADS=1 build/release/runner/foam-run studies/specs/fusion-2x20.toml --out ${OUT:-/tmp/fig8-pa1-probe}/step-dt$dt-s$s --force \
    --set seed=$s --set duration_s=3600 --set snapshot_every_s=0 --set sample_every_s=10 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=$dt \
    --set numerics.cg_tol=$cg --set cells.pa_reduced=1 --set cells.alpha=0.4375 --set cells.l_eta_reduced=0.5 \
    --set numerics.contact_within_prisms=true --set numerics.contact_prisms_overlap_only=true \
    --set scene.polarity_from_preparation=true --set numerics.remesh_rescue=true \
    --set numerics.max_volume_error=0.2 \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet > ${OUT:-/tmp/fig8-pa1-probe}/step-dt$dt-s$s.log 2>&1
}
run 0.5 0.01 1 & run 0.5 0.01 2 & wait
run 0.5 0.01 3
