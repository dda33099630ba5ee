#!/bin/bash
# p_a r/2γ 1, α 0.4375: the law at 0.25 s on seeds 2 and 3; the bound at 0.25 s on seed 1 (1200 s)
mkdir -p "${OUT:-/tmp/fig8-pa1-probe}"
cd "$(dirname "$0")/../../../.."
run() {
  lab=$1 dt=$2 cg=$3 b=$4 a=$5 s=$6
  OMP_NUM_THREADS=1 build/release/runner/foam-run studies/specs/fusion-2x20.toml --out ${OUT:-/tmp/fig8-pa1-probe}/cmp-$lab --force \
    --set seed=$s --set duration_s=1200 --set snapshot_every_s=0 --set sample_every_s=10 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=$dt \
    --set numerics.cg_tol=$cg --set cells.pa_reduced=1 --set cells.alpha=$a --set cells.l_eta_reduced=0.5 \
    --set numerics.contact_within_prisms=$b --set numerics.contact_prisms_overlap_only=$b \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet > ${OUT:-/tmp/fig8-pa1-probe}/cmp-$lab.log 2>&1
}
run bound025-a044 0.25 0.001 true 0.4375 1
run law025-a044-s2 0.25 0.001 false 0.4375 2
run law025-a044-s3 0.25 0.001 false 0.4375 3
run bound1-a044-s2 1 0.01 true 0.4375 2
run bound1-a044-s3 1 0.01 true 0.4375 3
