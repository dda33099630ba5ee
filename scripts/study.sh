#!/usr/bin/env bash
# Runs a study file (studies/*.toml) through foamd, resumably, and reports it (docs/science/).
#
#   scripts/study.sh run studies/fig14-reduced.toml [--report DIR] [--no-wait] [--retry-failed | --retry-kinds KINDS]
#   scripts/study.sh report studies/fig14-reduced.toml [--out DIR] [--from-data DIR]
#   scripts/study.sh check studies/fig14-reduced.toml
#   scripts/study.sh verdicts studies/verdicts.toml --data docs/science --out docs/science/verdicts
#   scripts/study.sh save-store DIR [--db DB]      (restore-store DIR: before foamd starts)
#
# With a foamd answering at FOAM_SERVER (default 127.0.0.1:50051) — a local one, or one with
# `--executor slurm` on a cluster — the study runs there. Otherwise this script starts one for
# the study's duration on a database that outlives it (FOAM_STUDY_DB, default
# ~/.local/share/activefoam/studies.db; FOAM_STUDY_WORKERS jobs at once, default the cores, one
# thread each) and stops it at the end: an interrupted study re-queues its running jobs, and the
# same command later resumes them from their checkpoints and submits only what is missing.
# Builds first when there is no build (scripts/build.sh release).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bin="${FOAM_BUILD_DIR:-$root/build/release}"
[ -x "$bin/server/foamd" ] && [ -d "$bin/python/activefoam" ] || "$root/scripts/build.sh" release
export PYTHONPATH="$bin/python${PYTHONPATH:+:$PYTHONPATH}" PYTHONDONTWRITEBYTECODE=1
py=/usr/bin/python3
study() { "$py" -m activefoam.study "$@"; }

cmd="${1:-}"
needs_server=1
case "$cmd" in
  check | verdicts | save-store | restore-store) needs_server=0 ;;
  report) for a in "$@"; do [ "$a" = --from-data ] && needs_server=0; done ;;
  run) ;;
  *) study --help; exit 2 ;;
esac

export FOAM_SERVER="${FOAM_SERVER:-127.0.0.1:50051}"
answers() { "$bin/client/foam" list --state running >/dev/null 2>&1; }
if [ "$needs_server" = 1 ] && ! answers; then
  case "$FOAM_SERVER" in
    127.*:* | localhost:* | "[::1]":*) ;;
    *) echo "study.sh: no foamd answers at $FOAM_SERVER (a remote server is not started" \
         "from here: start it there, or unset FOAM_SERVER for a local one)" >&2
       exit 3 ;;
  esac
  db="${FOAM_STUDY_DB:-${XDG_DATA_HOME:-$HOME/.local/share}/activefoam/studies.db}"
  mkdir -p "$(dirname "$db")"
  log="${db%.db}-foamd.log"
  workers="${FOAM_STUDY_WORKERS:-$(nproc)}"
  echo "study.sh: no foamd at $FOAM_SERVER; starting one: --db $db --workers $workers" \
    "--threads-per-job 1 (log: $log)" >&2
  OMP_NUM_THREADS=1 "$bin/server/foamd" --listen "$FOAM_SERVER" --db "$db" --workers "$workers" \
    --threads-per-job 1 >>"$log" 2>&1 &
  foamd_pid=$!
  # TERM: foamd checkpoints and re-queues its running jobs; the next run resumes them.
  trap 'kill -TERM $foamd_pid 2>/dev/null || true; wait $foamd_pid 2>/dev/null || true' EXIT
  for _ in $(seq 100); do answers && break; sleep 0.2; done
  answers || { echo "study.sh: foamd did not start; see $log" >&2; tail -5 "$log" >&2; exit 3; }
fi
study "$@"
