#!/usr/bin/env bash
# Runs a page's list of runs, one foam-run each, into OUT/NAME-seedS/: a finished run is left
# alone, an interrupted one resumes from its checkpoint, so the command can be stopped and
# given again. A run that fails (a result too: its folder says why) does not stop the list; the
# exit status is then 1, after the last run, naming the failed ones.
#
#   docs/science/tools/run_list.sh LIST OUT [GROUP...]
#
# LIST: lines "GROUP NAME SEED SPEC [KEY=VALUE...]" (SPEC relative to LIST's folder; '#' starts
# a comment); only the named GROUPs' lines run (default: all), in the list's order. foam-run is
# $FOAM_RUN, else build/release/runner/foam-run; one thread each ($OMP_NUM_THREADS=1).
set -euo pipefail
[ $# -ge 2 ] || { sed -n 2,10p "$0" >&2; exit 2; }
list=$1 out=$2
shift 2
here=$(cd "$(dirname "$list")" && pwd)
root=$(cd "$(dirname "$0")/../../.." && pwd)
run=${FOAM_RUN:-$root/build/release/runner/foam-run}
[ -x "$run" ] || { echo "run_list.sh: no foam-run at $run (build it, or set FOAM_RUN)" >&2; exit 2; }
want=" $* "
n=0 failed=()
while read -r group name seed spec settings; do
  case $group in ''|'#'*) continue ;; esac
  [ $# -eq 0 ] || [[ $want == *" $group "* ]] || continue
  sets=(--set "seed=$seed")
  for s in $settings; do sets+=(--set "$s"); done
  dir="$out/$name-seed$seed"
  echo "run_list.sh: $dir" >&2
  OMP_NUM_THREADS=1 "$run" "$here/$spec" --out "$dir" --resume --quiet "${sets[@]}" < /dev/null ||
    failed+=("$dir")
  n=$((n + 1))
done < "$list"
[ $n -gt 0 ] || { echo "run_list.sh: no line of $list in the groups:$want" >&2; exit 2; }
[ ${#failed[@]} -eq 0 ] || { echo "run_list.sh: failed: ${failed[*]}" >&2; exit 1; }
