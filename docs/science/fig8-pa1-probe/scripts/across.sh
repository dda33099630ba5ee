#!/bin/bash
# p_a r/2γ = 1 across α, 1 h each (the base spec's [spec] of the figure studies with the prepared
# polarities, the remesher's rescue and the volume guard at 20 %), at three steps:
#   b05  Δt 0.5 s / ε_CG 1e-2 with the overlap within prisms
#   b025 Δt 0.25 s / ε_CG 1e-3 with the overlap within prisms
#   l025 Δt 0.25 s / ε_CG 1e-3 under the plain law (the figure studies' step)
# One one-thread foam-run per run, JOBS at once (default the cores); the folders are across/'s.
# On a 16-core machine the runs were stopped after 440 s (b05) and 290 s
# (b025, l025) of wall time: LIMIT_S does the same (default none).
#   OUT=/tmp/across docs/science/fig8-pa1-probe/scripts/across.sh            # all 30
#   OUT=/tmp/across docs/science/fig8-pa1-probe/scripts/across.sh b05-a0.3-s4 # one
set -euo pipefail
cd "$(dirname "$0")/../../../.."
out=${OUT:-/tmp/fig8-pa1-probe/across}
mkdir -p "$out"
runs=("$@")
if [ ${#runs[@]} -eq 0 ]; then
  for s in 1 2 3 4 5 6; do runs+=(b05-a0.3-s$s b025-a0.3-s$s l025-a0.3-s$s); done
  for s in 1 2 3 4 5; do runs+=(b05-a0.4375-s$s b05-a0.75-s$s); done
  runs+=(b025-a0.4375-s5 l025-a0.4375-s5)
fi
one() {
  local name=$1 k a s x=()
  k=${name%%-*}; a=${name#*-a}; a=${a%%-*}; s=${name##*-s}
  case $k in
    b05) x=(--set numerics.dt_s=0.5 --set numerics.cg_tol=0.01) ;;
    *) x=(--set numerics.dt_s=0.25 --set numerics.cg_tol=0.001) ;;
  esac
  case $k in
    b*) x+=(--set numerics.contact_within_prisms=true --set numerics.contact_prisms_overlap_only=true) ;;
  esac
  local lim=()
  [ -n "${LIMIT_S:-}" ] && lim=(timeout -s TERM "$LIMIT_S")
  OMP_NUM_THREADS=1 "${lim[@]}" build/release/runner/foam-run studies/specs/fusion-2x20.toml \
    --out "$out/$name" --force --set seed="$s" --set duration_s=3600 --set snapshot_every_s=0 \
    --set sample_every_s=10 --set numerics.integrator=contact-implicit-consistent "${x[@]}" \
    --set cells.pa_reduced=1 --set cells.alpha="$a" --set cells.l_eta_reduced=0.5 \
    --set scene.polarity_from_preparation=true --set numerics.remesh_rescue=true \
    --set numerics.max_volume_error=0.2 \
    --spheroid-cache ~/.local/share/activefoam/spheroids --threads 1 --quiet \
    >"$out/$name.log" 2>&1 || true
  cp "$out/$name.log" "$out/$name/foam-run.log" 2>/dev/null || true
}
export -f one
export out
printf '%s\n' "${runs[@]}" | xargs -P "${JOBS:-$(nproc)}" -I{} bash -c 'one {}'
