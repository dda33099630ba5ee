#!/bin/bash
# the corner (p_a r/2γ 1, α 0.3), seed 1, 600 s: label dt cg bound
mkdir -p "${OUT:-/tmp/fig8-pa1-probe}"
cd "$(dirname "$0")/../../../.."
run() {
  lab=$1 dt=$2 cg=$3 b=$4
  OMP_NUM_THREADS=1 build/release/runner/foam-run studies/specs/fusion-2x20.toml --out ${OUT:-/tmp/fig8-pa1-probe}/cmp-$lab --force \
    --set seed=1 --set duration_s=600 --set snapshot_every_s=0 --set sample_every_s=10 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s=$dt \
    --set numerics.cg_tol=$cg --set cells.pa_reduced=1 --set cells.alpha=0.3 --set cells.l_eta_reduced=0.5 \
    --set numerics.contact_within_prisms=$b --set numerics.contact_prisms_overlap_only=$b \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet > ${OUT:-/tmp/fig8-pa1-probe}/cmp-$lab.log 2>&1
}
run law025 0.25 0.001 false
run bound025 0.25 0.001 true
run bound05 0.5 0.01 true
