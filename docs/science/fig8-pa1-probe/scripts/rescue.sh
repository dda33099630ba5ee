#!/bin/bash
# p_a r/2γ 1, α 0.4375, Δt 1 s / ε_CG 1e-2 with the overlap within prisms, the prepared
# polarities and numerics.remesh_rescue, 1 200 s: seed 3 (which locked a sliver at 189 s without
# the rescue) with the volume guard at 5 % and at 10 %, seed 2 at 5 %.
#   OUT=/tmp/fig8-pa1-probe docs/science/fig8-pa1-probe/scripts/rescue.sh
mkdir -p "${OUT:-/tmp/fig8-pa1-probe}"
cd "$(dirname "$0")/../../../.."
run() {
  lab=$1 s=$2 guard=$3
  OMP_NUM_THREADS=1 build/release/runner/foam-run studies/specs/fusion-2x20.toml --out ${OUT:-/tmp/fig8-pa1-probe}/rescue-$lab --force \
    --set seed=$s --set duration_s=1200 --set snapshot_every_s=0 --set sample_every_s=5 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=1 \
    --set numerics.cg_tol=0.01 --set cells.pa_reduced=1 --set cells.alpha=0.4375 --set cells.l_eta_reduced=0.5 \
    --set numerics.contact_within_prisms=true --set numerics.contact_prisms_overlap_only=true \
    --set scene.polarity_from_preparation=true --set numerics.remesh_rescue=true \
    --set numerics.max_volume_error=$guard \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet > ${OUT:-/tmp/fig8-pa1-probe}/rescue-$lab.log 2>&1
}
run s3 3 0.05 &
run s3-guard10 3 0.1 &
wait
run s2 2 0.05
