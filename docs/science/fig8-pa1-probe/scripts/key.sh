#!/bin/bash
# p_a r/2γ 1, α 0.4375: scene.polarity_from_preparation = true, the normal guard, 300 s
mkdir -p "${OUT:-/tmp/fig8-pa1-probe}"
cd "$(dirname "$0")/../../../.."
run() {
  lab=$1 dt=$2 cg=$3 b=$4 s=$5
  OMP_NUM_THREADS=1 build/release/runner/foam-run studies/specs/fusion-2x20.toml --out ${OUT:-/tmp/fig8-pa1-probe}/key-$lab --force \
    --set seed=$s --set duration_s=300 --set snapshot_every_s=0 --set sample_every_s=5 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=$dt \
    --set numerics.cg_tol=$cg --set cells.pa_reduced=1 --set cells.alpha=0.4375 --set cells.l_eta_reduced=0.5 \
    --set numerics.contact_within_prisms=$b --set numerics.contact_prisms_overlap_only=$b \
    --set scene.polarity_from_preparation=true \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet > ${OUT:-/tmp/fig8-pa1-probe}/key-$lab.log 2>&1
}
run bound1-s2 1 0.01 true 2
run bound1-s3 1 0.01 true 3
run law025-s2 0.25 0.001 false 2
run law025-s3 0.25 0.001 false 3
