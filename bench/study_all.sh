#!/usr/bin/env bash
# The whole speed/accuracy study in one command: builds the release tree, then
# regenerates into docs/study/ the doublet study and its chart, the stability map and the
# reduced-fusion study and its chart. Every study drives one core (OMP_NUM_THREADS=1) so costs
# compare; the fusion study is resumable — run this again after an interruption and finished
# rows are kept (delete docs/study/fusion/runs to start over).
#
#   bench/study_all.sh [--skip-doublet] [--skip-map] [--skip-fusion]
#
# Wall time on the 2-core machine: doublet ~25 min, map ~15 min, fusion ~3 h.
set -euo pipefail
cd "$(dirname "$0")/.."
doublet=1 map=1 fusion=1
for a in "$@"; do
  case "$a" in
    --skip-doublet) doublet=0 ;;
    --skip-map) map=0 ;;
    --skip-fusion) fusion=0 ;;
    *) echo "study_all.sh: unknown option '$a' (allowed: --skip-doublet, --skip-map, --skip-fusion)" >&2; exit 2 ;;
  esac
done
./scripts/build.sh release
export OMP_NUM_THREADS=1
if ((doublet)); then
  echo "== doublet: every knob against a 1280-triangle reference" >&2
  build/release/bench/study_accuracy docs/study
  python3 bench/plot_study.py docs/study/doublet.csv docs/study/doublet-pareto.png \
    "doublet (alpha = 0.4375, 1500 s): error against cost"
fi
if ((map)); then
  echo "== stability map: largest stable dt against k_AB and motility" >&2
  build/release/bench/study_stability_map docs/study 200
  python3 bench/plot_stability_map.py docs/study/stability-map.csv docs/study/stability-map.png
fi
if ((fusion)); then
  echo "== reduced fusion: 2 x 30 cells, 30 simulated minutes" >&2
  python3 bench/study_fusion_accuracy.py docs/study/fusion
  python3 bench/plot_study.py docs/study/fusion/fusion.csv docs/study/fusion/fusion-pareto.png \
    "fusion of 2 x 30 cells, 30 min: error against cost"
fi
echo "study_all.sh: done; see docs/study/README.md" >&2
