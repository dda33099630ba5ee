#!/bin/bash
# numerics.remesh_rebuild, 1 h each, the prepared polarities and the rescue, guard 20 %:
#   b05-a0.4375-s5   p_a r/2γ = 1, α 0.4375, seed 5, Δt 0.5 s / 1e-2 with the bound: without the
#                    rebuild it ended on a sliver at 674 s (across/b05-a0.4375-s5)
#   base-dt1-s1[-norebuild]  the base point (p_a r/2γ = 0.33) at Δt 1 s / 1e-2 with the bound, seed 1,
#                    with and without the key: a run the rebuild never touches keeps its bits
# Further runs by name: KIND-aALPHA-sSEED with KIND b05 or b1 (Δt 0.5 or 1 s with the bound, p_a = 1).
#   OUT=/tmp/rebuild docs/science/fig8-pa1-probe/scripts/rebuild.sh [NAME ...]
set -euo pipefail
cd "$(dirname "$0")/../../../.."
out=${OUT:-/tmp/fig8-pa1-probe/rebuild}
mkdir -p "$out"
one() {
  local name=$1 pa=1 a s dt x=(--set numerics.remesh_rebuild=true)
  case $name in
    base-dt1-s1) pa=0.33 a=0.4375 s=1 dt=1 ;;
    base-dt1-s1-norebuild) pa=0.33 a=0.4375 s=1 dt=1 x=() ;;
    b05-*|b1-*) a=${name#*-a}; a=${a%%-*}; s=${name##*-s}; dt=${name%%-*}; dt=${dt#b}
      [ "$dt" = 05 ] && dt=0.5 ;;
    *) echo "unknown run $name" >&2; return 2 ;;
  esac
  OMP_NUM_THREADS=1 build/release/runner/foam-run studies/specs/fusion-2x20.toml --out "$out/$name" \
    --force --set seed="$s" --set duration_s=3600 --set snapshot_every_s=0 --set sample_every_s=10 \
    --set numerics.integrator=contact-implicit-consistent --set numerics.dt_s="$dt" \
    --set numerics.cg_tol=0.01 --set cells.pa_reduced="$pa" --set cells.alpha="$a" \
    --set cells.l_eta_reduced=0.5 --set numerics.contact_within_prisms=true \
    --set numerics.contact_prisms_overlap_only=true --set scene.polarity_from_preparation=true \
    --set numerics.remesh_rescue=true --set numerics.max_volume_error=0.2 ${x[@]+"${x[@]}"} \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet >"$out/$name.log" 2>&1 || true
  cp "$out/$name.log" "$out/$name/foam-run.log" 2>/dev/null || true
}
export -f one
export out
names=("$@")
[ ${#names[@]} -gt 0 ] || names=(b05-a0.4375-s5 base-dt1-s1 base-dt1-s1-norebuild)
printf '%s\n' "${names[@]}" | xargs -P "${JOBS:-$(nproc)}" -I{} bash -c 'one {}'
