#!/usr/bin/env bash
# The project's study campaign (the studies of studies/campaign.txt, in that order) on machines
# that do not outlive a working session: one foamd store holds the queue, and it is carried from
# one session to the next in studies/store/ (scripts/study.sh save-store / restore-store), so a
# run cut off by the end of a session resumes from its checkpoint in the next.
#
#   scripts/campaign.sh start [--engine-changed] [--cancel-stale]
#       restores the store from studies/store/ when there is none here, starts foamd on it (one
#       one-thread job per core) and submits what is missing: a run whose results are committed
#       (docs/science/NAME/data) counts as done even if the store was lost. foamd is built from
#       the engine the store's jobs ran, in a worktree when the checkout's engine differs;
#       --engine-changed runs the checkout's engine instead, from then on (only after checking
#       that it gives a stored job's samples the same bits: the running jobs resume under it).
#       Queued or running jobs that are no run of their study file as it is now (a study moved
#       to another step) are named; --cancel-stale cancels them.
#   scripts/campaign.sh report    every study with ended runs: docs/science/NAME (figures, data),
#                                 and the verdict table (docs/science/verdicts)
#   scripts/campaign.sh stop      stops foamd (its running jobs checkpoint and re-queue) and saves
#                                 the store to studies/store/ (commit it with the reports)
#   scripts/campaign.sh status    the queue by study and state
#
# CAMPAIGN_DB: the store (default ~/.local/share/activefoam/campaign.db); FOAM_SERVER: where its
# foamd listens (default 127.0.0.1:50051); CAMPAIGN_WORKERS: jobs at once (default the cores);
# CAMPAIGN_FILE, CAMPAIGN_SAVED, CAMPAIGN_SCIENCE: the list, the saved store and the reports'
# folder (defaults studies/campaign.txt, studies/store, docs/science).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bin="${FOAM_BUILD_DIR:-$root/build/release}"
db="${CAMPAIGN_DB:-${XDG_DATA_HOME:-$HOME/.local/share}/activefoam/campaign.db}"
export FOAM_SERVER="${FOAM_SERVER:-127.0.0.1:50051}"
saved="${CAMPAIGN_SAVED:-$root/studies/store}"
science="${CAMPAIGN_SCIENCE:-$root/docs/science}"
pidfile="${db%.db}-foamd.pid"
enginefile="${db%.db}-engine.txt"
study() { "$root/scripts/study.sh" "$@"; }
list="${CAMPAIGN_FILE:-$root/studies/campaign.txt}"
studies() { grep -v '^\s*#' "$list" | awk 'NF {print $1}'; }
name_of() { basename "$1" .toml; }
running() { [ -f "$pidfile" ] && kill -0 "$(cat "$pidfile")" 2>/dev/null; }
answers() { "$bin/client/foam" list --state running >/dev/null 2>&1; }
count() {  # STUDY STATE...: its jobs in those states
  local n=$1
  shift
  "$bin/client/foam" list --limit 1000 --tag "study:$n" --state "$@" 2>/dev/null |
    tail -n +2 | wc -l
}

cmd="${1:-}"
shift || true
case "$cmd" in
  start)
    if [ ! -x "$bin/server/foamd" ] || [ ! -x "$bin/client/foam" ] ||
      [ ! -d "$bin/python/activefoam" ]; then
      # What the campaign needs only (foamd, foam, the Python client): on a fresh machine the
      # runs start minutes before the whole build with its tests would be done.
      "$root/scripts/setup-deps.sh"
      (cd "$root" && export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=1 &&
        cmake --preset release >/dev/null &&
        cmake --build --preset release -j "$(nproc)" --target foamd foam python_client)
    fi
    if running; then
      echo "campaign: foamd already runs (pid $(cat "$pidfile"))" >&2
    else
      # The engine the store's jobs run on is the one that wrote their checkpoints (they resume
      # bit for bit only under it): the last start's on this machine, else the saved copy's,
      # else this checkout's. When the checkout's engine has moved on since, that engine's
      # foamd is built from its commit in a worktree (build/campaign-engine), so the campaign
      # goes on unchanged while the engine is developed.
      here_tree="$(git -C "$root" rev-parse HEAD:engine 2>/dev/null || echo unknown)"
      here_commit="$(git -C "$root" rev-parse HEAD 2>/dev/null || echo -)"
      want_tree="$here_tree" want_commit="$here_commit"
      restoring=0
      if [ -f "$db" ] && [ -f "$enginefile" ]; then
        read -r want_tree want_commit <"$enginefile"
      elif [ ! -f "$db" ] && [ -f "$saved/MANIFEST.json" ]; then
        restoring=1
        read -r want_tree want_commit < <(/usr/bin/python3 -c 'import json, sys
m = json.load(open(sys.argv[1]))
print(m.get("engine") or "unknown", m.get("engine_commit") or "-")' "$saved/MANIFEST.json")
      fi
      foamd_bin="$bin/server/foamd"
      if [ "$want_tree" != "$here_tree" ] && [[ " $* " == *" --engine-changed "* ]]; then
        # The operator checked that the checkout's engine gives the store's runs the same bits
        # (a stored job's samples rerun with it): it takes over, checkpoints and all.
        echo "campaign: the store's engine was $want_tree (commit $want_commit); this" \
          "checkout's $here_tree takes over (--engine-changed)" >&2
        want_tree="$here_tree" want_commit="$here_commit"
      fi
      if [ "$want_tree" != "$here_tree" ]; then
        if [ "${want_commit:--}" != - ] &&
          git -C "$root" cat-file -e "$want_commit^{commit}" 2>/dev/null &&
          [ "$(git -C "$root" rev-parse "$want_commit:engine")" = "$want_tree" ]; then
          wt="$root/build/campaign-engine"
          if [ -e "$wt/.git" ]; then
            git -C "$wt" checkout -q --detach "$want_commit"
          else
            git -C "$root" worktree add -q --detach "$wt" "$want_commit"
          fi
          echo "campaign: the store's engine is $want_tree (commit $want_commit), this" \
            "checkout's $here_tree: building that foamd in $wt" >&2
          (cd "$wt" && export CCACHE_BASEDIR="$wt" CCACHE_NOHASHDIR=1 &&
            cmake --preset release >/dev/null &&
            cmake --build --preset release -j "$(nproc)" --target foamd >/dev/null)
          foamd_bin="$wt/build/release/server/foamd"
        else
          echo "campaign: the store's jobs ran engine $want_tree, of no commit here; this" \
            "checkout's is $here_tree. If the step's results did not change, start with" \
            "--engine-changed; otherwise cancel the running jobs after starting so" >&2
          exit 2
        fi
      fi
      if [ "$foamd_bin" = "$bin/server/foamd" ] &&
        [ -n "$(git -C "$root" status --porcelain -- engine 2>/dev/null)" ]; then
        echo "campaign: engine/ has uncommitted changes: commit them before running studies" >&2
        exit 2
      fi
      if [ "$restoring" = 1 ]; then
        study restore-store "$saved" --db "$db" --engine "$want_tree" "$@"
      fi
      mkdir -p "$(dirname "$db")"
      echo "$want_tree $want_commit" >"$enginefile"
      # A copy of the binary: rebuilding during the session does not change what runs.
      cp "$foamd_bin" "${db%.db}-foamd"
      OMP_NUM_THREADS=1 setsid nohup "${db%.db}-foamd" --listen "$FOAM_SERVER" --db "$db" \
        --workers "${CAMPAIGN_WORKERS:-$(nproc)}" --threads-per-job 1 >>"${db%.db}-foamd.log" 2>&1 &
      echo $! >"$pidfile"
      for _ in $(seq 100); do answers && break; sleep 0.2; done
      answers || { echo "campaign: foamd did not start; see ${db%.db}-foamd.log" >&2; exit 3; }
      echo "campaign: foamd (pid $(cat "$pidfile")) on $db at $FOAM_SERVER" >&2
    fi
    for f in $(studies); do
      data="$science/$(name_of "$f")/data"
      with=()
      [ -f "$data/runs.csv" ] && with=(--with-data "$data")
      [[ " $* " == *" --cancel-stale "* ]] && with+=(--cancel-stale)
      study run "$(dirname "$list")/$f" --no-wait "${with[@]}"
    done
    ;;
  report)
    answers || { echo "campaign: no foamd at $FOAM_SERVER (campaign.sh start)" >&2; exit 3; }
    for f in $(studies); do
      n="$(name_of "$f")"
      out="$science/$n"
      with=()
      [ -f "$out/data/runs.csv" ] && with=(--with-data "$out/data")
      if [ "$(count "$n" succeeded failed)" = 0 ] && [ ${#with[@]} = 0 ]; then
        echo "campaign: $n: no run has ended yet" >&2
        continue
      fi
      study report "$(dirname "$list")/$f" --out "$out" "${with[@]}" >/dev/null
      echo "campaign: $n reported in $out" >&2
    done
    # The verdict table from every study's data (rows whose runs have not ended say so).
    verdicts="$(dirname "$list")/verdicts.toml"
    if [ -f "$verdicts" ]; then
      study verdicts "$verdicts" --data "$science" --out "$science/verdicts" >/dev/null
      echo "campaign: verdicts in $science/verdicts" >&2
    fi
    ;;
  stop)
    if running; then
      pid="$(cat "$pidfile")"
      kill -TERM "$pid"
      for _ in $(seq 600); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
      if kill -0 "$pid" 2>/dev/null; then
        echo "campaign: foamd (pid $pid) has not stopped after 120 s; not saving" >&2
        exit 3
      fi
      rm -f "$pidfile"
    fi
    [ -f "$db" ] || { echo "campaign: no store at $db" >&2; exit 2; }
    # Without the snapshots: a 6 h run's are ~1 MB, no report reads them, and the copy is
    # committed every session.
    read -r tree commit <"$enginefile" 2>/dev/null || tree=unknown commit=""
    study save-store "$saved" --db "$db" --without-snapshots --engine "$tree" \
      --engine-commit "${commit:-}"
    echo "campaign: saved to $saved (commit it with the reports)" >&2
    ;;
  status)
    answers || { echo "campaign: no foamd at $FOAM_SERVER" >&2; exit 3; }
    for f in $(studies); do
      n="$(name_of "$f")"
      printf '%-16s' "$n"
      for s in running queued succeeded failed; do
        printf ' %3d %s' "$(count "$n" "$s")" "$s"
      done
      echo
    done
    echo "running now:"
    "$bin/client/foam" list --state running | tail -n +2 | awk '{print "  " $1, $NF, $6}'
    ;;
  *)
    awk 'NR > 1 && /^#/ {sub(/^# ?/, ""); print; next} NR > 1 {exit}' "$0"
    exit 2
    ;;
esac
