#!/bin/bash
# How far cells' volumes swing at p_a r/2γ = 1 when the guard does not stop the run: Δt 1 s /
# ε_CG 1e-2 with the overlap within prisms, the prepared polarities and numerics.remesh_rescue,
# volume guard 20 %, 1 h, samples every 10 s; α 0.4375 seeds 1–3, α 0.3 seeds 1–2. Two at a time.
#   OUT=/tmp/fig8-pa1-probe docs/science/fig8-pa1-probe/scripts/guard.sh
mkdir -p "${OUT:-/tmp/fig8-pa1-probe}"
cd "$(dirname "$0")/../../../.."
run() {
  a=$1 s=$2
  OMP_NUM_THREADS=1 build/release/runner/foam-run studies/specs/fusion-2x20.toml --out ${OUT:-/tmp/fig8-pa1-probe}/guard20-a$a-s$s --force \
    --set seed=$s --set duration_s=3600 --set snapshot_every_s=0 --set sample_every_s=10 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=1 \
    --set numerics.cg_tol=0.01 --set cells.pa_reduced=1 --set cells.alpha=$a --set cells.l_eta_reduced=0.5 \
    --set numerics.contact_within_prisms=true --set numerics.contact_prisms_overlap_only=true \
    --set scene.polarity_from_preparation=true --set numerics.remesh_rescue=true \
    --set numerics.max_volume_error=0.2 \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet > ${OUT:-/tmp/fig8-pa1-probe}/guard20-a$a-s$s.log 2>&1
}
run 0.4375 1 & run 0.4375 2 & wait
run 0.4375 3 & run 0.3 1 & wait
run 0.3 2
