"""The study tool's command line: python3 -m activefoam.study (or foam-study) run | report |
check | verdicts | power | save-store | restore-store."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any, List, Optional, Sequence

from activefoam.inputs import read_token_file
from activefoam.study import store_copy
from activefoam.study.data import collect, load_data
from activefoam.study.matching import Carried, carried_runs
from activefoam.study.outputs import check_folder
from activefoam.study.report import render
from activefoam.study.studyfile import Study, StudyError, load
from activefoam.study.submission import (_retry_kinds, cancel_stale, submit_diagnoses,
                                         submit_missing, wait)


def _client(args: Any) -> Any:
    from activefoam.client import Client
    return Client(args.server, token=_token(args), tls_ca=args.tls_ca)


def _token(args: Any) -> Optional[str]:
    # --token-file '' is an error (read_token_file says so), not "no auth".
    if args.token_file is not None:
        return read_token_file(args.token_file)
    return None


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        return _main(argv)
    except ValueError as e:  # StudyError, or a spec foamd refused
        print(f"error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # a ConnectionError too, but of stdout (`check | head`)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as e:
        if e.filename is not None:  # a file that could not be written or read: which one
            print(f"error: {e.filename}: {e.strerror or e}", file=sys.stderr)
            return 2
        if isinstance(e, PermissionError):  # foamd refused the token
            print(f"error: {e}", file=sys.stderr)
            return 4
        if isinstance(e, ConnectionError):
            print(f"error: {e} (is foamd running? --server / FOAM_SERVER)", file=sys.stderr)
            return 3
        raise
    except KeyboardInterrupt:
        print("\ninterrupted: the submitted jobs go on in foamd; run the same command again to "
              "follow them (nothing is submitted twice)", file=sys.stderr)
        return 130


def _main(argv: List[str]) -> int:
    if argv[:1] == ["power"]:  # its own options (activefoam.study.power)
        from activefoam.study import power
        return power.main(argv[1:])
    ap = argparse.ArgumentParser(
        prog="python3 -m activefoam.study",
        description="Run a study file through foamd (resumable) and report it from the store.")
    ap.add_argument("--server", default=None, help="foamd address (default FOAM_SERVER or "
                    "127.0.0.1:50051)")
    ap.add_argument("--token-file", default=None, help="bearer token file (default FOAM_TOKEN)")
    ap.add_argument("--tls-ca", default=None, help="PEM of foamd's certificate or CA")
    ap.add_argument("--base-root", default=None, metavar="DIR",
                    help="the folder a study's `base =` file may be read from (default: the "
                    "study file's own folder)")
    sub = ap.add_subparsers(dest="cmd", required=True)
    p_run = sub.add_parser("run", help="submit the runs that are missing or failed, then wait")
    p_run.add_argument("study")
    p_run.add_argument("--no-wait", action="store_true", help="submit and return")
    p_run.add_argument("--retry-failed", action="store_true",
                       help="also rerun runs that failed in the simulation itself")
    p_run.add_argument("--retry-kinds", metavar="KINDS", default=None,
                       help="also rerun the runs that failed in the simulation with one of these "
                       "failure kinds (comma-separated, e.g. preparation-failed)")
    p_run.add_argument("--cancel-stale", action="store_true",
                       help="cancel the study's queued or running jobs that are no run of the "
                       "file as it is now (an earlier version's [spec], grid or seeds); without "
                       "it they are only named")
    p_run.add_argument("--report", metavar="DIR", default=None,
                       help="when every run has ended, collect and report into DIR")
    p_run.add_argument("--poll", type=float, default=2.0, help=argparse.SUPPRESS)
    with_data_help = ("a report's data folder from an earlier store (e.g. the committed "
                      "docs/science/NAME/data): the runs it holds as ended count as done, are "
                      "not submitted again, and are reported with the store's; a diagnosis "
                      "rerun it lists as queued or running is submitted here")
    p_run.add_argument("--with-data", default=None, metavar="DIR", help=with_data_help)
    p_rep = sub.add_parser("report", help="tables and figures from the store (or --from-data)")
    p_rep.add_argument("study")
    p_rep.add_argument("--out", default=None, help="output folder (default: next to the study "
                       "file, NAME-report/)")
    p_rep.add_argument("--from-data", default=None, metavar="DIR",
                       help="render from a data folder written by an earlier report (runs.csv, "
                            "samples.csv.gz, msrd.csv.gz) instead of the store")
    p_rep.add_argument("--with-data", default=None, metavar="DIR", help=with_data_help)
    p_chk = sub.add_parser("check", help="read the study file and list its runs")
    p_chk.add_argument("study")
    p_ver = sub.add_parser("verdicts", help="judge the supplement's trend statements (a "
                           "verdicts file) on the studies' committed data")
    p_ver.add_argument("study", metavar="VERDICTS", help="verdicts file (studies/verdicts.toml)")
    p_ver.add_argument("--data", required=True, metavar="DIR",
                       help="folder of the studies' reports: DIR/NAME/data for each study")
    p_ver.add_argument("--out", required=True, metavar="DIR", help="writes verdicts.md and .csv")
    sub.add_parser("power", add_help=False,
                   help="the effects a study's seeds can resolve, the fitness rule on synthetic "
                   "ensembles, how long paired runs stay together (power --help)")
    default_db = os.environ.get("FOAM_STUDY_DB") or str(
        Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local/share") /
        "activefoam/studies.db")
    p_sav = sub.add_parser("save-store", help="copy foamd's store (jobs, results, running jobs' "
                           "checkpoints, prepared spheroids) to a folder, foamd running or not")
    p_sav.add_argument("dir", metavar="DIR")
    p_sav.add_argument("--db", default=default_db, help=f"the store (default {default_db})")
    p_sav.add_argument("--engine", default=None, help="the engine the store's jobs ran "
                       "(default: git tree of this checkout's engine/)")
    p_sav.add_argument("--without-snapshots", action="store_true",
                       help="leave the jobs' snapshots (3D frames) out of the copy")
    p_sav.add_argument("--engine-commit", default="", help="a commit whose engine/ is that "
                       "engine (the next machine can build the same foamd from it)")
    p_res = sub.add_parser("restore-store", help="put a saved store back (before foamd starts "
                           "on it): its running jobs resume from their checkpoints")
    p_res.add_argument("dir", metavar="DIR")
    p_res.add_argument("--db", default=default_db, help=f"the store (default {default_db}); "
                       "must not exist")
    p_res.add_argument("--engine-changed", action="store_true",
                       help="restore a copy saved under another engine (only when the step's "
                            "results are bit-identical)")
    p_res.add_argument("--engine", default=None, help="the engine the restored store's foamd "
                       "will run (default: git tree of this checkout's engine/)")
    p_res.add_argument("--max-unpacked-gib", type=float,
                       default=store_copy.MAX_UNPACKED_BYTES / 2**30, metavar="GIB",
                       help="the most the two archives may unpack to together (default "
                       "%(default)g GiB): a damaged or hostile copy stops there")
    args = ap.parse_args(argv)
    if args.cmd in ("save-store", "restore-store"):
        try:
            if args.cmd == "save-store":
                m = store_copy.save(args.db, args.dir, engine=args.engine,
                                    snapshots=not args.without_snapshots,
                                    engine_commit=args.engine_commit)
            else:
                if not 0 < args.max_unpacked_gib < 2**20:  # nan and inf too
                    raise StudyError(f"--max-unpacked-gib: {args.max_unpacked_gib} is not "
                                     "a size in (0, 2^20) GiB")
                m = store_copy.restore(args.dir, args.db, engine=args.engine,
                                       engine_changed_ok=args.engine_changed,
                                       max_unpacked=int(args.max_unpacked_gib * 2**30))
        except store_copy.StoreCopyError as e:
            raise StudyError(str(e)) from None
        by_state = m.get("by_state")
        states = ", ".join(f"{n} {s}" for s, n in by_state.items()) \
            if isinstance(by_state, dict) else "?"
        print(f"{args.cmd}: {m.get('jobs', '?')} jobs ({states}), "
              f"{m.get('checkpoints', '?')} checkpoints, {m.get('spheroids', '?')} prepared "
              f"spheroids; engine {m.get('engine', '?')}, saved {m.get('saved_utc', '?')}",
              file=sys.stderr)
        return 0
    if args.cmd == "verdicts":
        from activefoam.study import verdicts
        def rel(x: str) -> str:  # as typed from the checkout, not this machine's paths
            r = os.path.relpath(x)
            return x if r.startswith("..") else r
        command = (f"scripts/study.sh verdicts {rel(args.study)} --data {rel(args.data)} "
                   f"--out {rel(args.out)}")
        for f in verdicts.write(verdicts.load(args.study), args.data, args.out,
                                command=command):
            print(f)
        return 0
    study = load(args.study, base_root=args.base_root)
    if args.cmd == "check":
        runs = study.runs()
        print(f"study {study.name}: {len(study.points())} points × {len(study.seeds)} seeds "
              f"= {len(runs)} runs, tag {study.tag}")
        for p in study.points():
            held = [x for x in study.shares if x.covers(p)]
            print("  " + ", ".join(f"{k}={v}" for k, v in p.items()) + "".join(
                f"  (shared: {sh.other.name}'s " +
                ", ".join(f"{k}={v}" for k, v in sh.that.items()) +
                (f" at seeds {sh.seeds}" if sh.seeds is not None else "") + ")"
                for sh in held))
        return 0
    # Where the report goes is checked before any work (report --out /dev/full).
    out = check_folder(args.out or study.path.parent / f"{study.name}-report") \
        if args.cmd == "report" else None
    if args.cmd == "run" and args.report:
        check_folder(args.report, "--report")
    if getattr(args, "with_data", None) and args.cmd == "report" and args.from_data:
        raise StudyError("--with-data: not with --from-data (which reads no store)")

    def carry(c: Any) -> Optional[Carried]:
        if not getattr(args, "with_data", None):
            return None
        carried = carried_runs(study, args.with_data, c)
        print(f"study {study.name}: {len(carried.rows)} ended runs in {args.with_data}",
              file=sys.stderr)
        return carried

    if args.cmd == "run":
        if args.retry_failed and args.retry_kinds:
            raise StudyError("--retry-failed reruns every failure kind: not with "
                             "--retry-kinds")
        retry = True if args.retry_failed else _retry_kinds(args.retry_kinds)
        with _client(args) as c:
            carried = carry(c)
            # Stale jobs first: a changed step must not leave the old one's queue running.
            cancel_stale(study, c, args.cancel_stale)
            n_new, n_held = submit_missing(study, c, retry_failed=retry,
                                           carried=carried)
            print(f"study {study.name}: {n_new} runs submitted, {n_held} already in the "
                  f"store{' or the data' if carried else ''} (tag {study.tag})",
                  file=sys.stderr)
            submit_diagnoses(study, c, carried=carried)
            if args.no_wait:
                return 0
            counts = wait(study, c, poll_s=args.poll, carried=carried)
            print(f"study {study.name}: " + ", ".join(f"{n} {s}" for s, n in
                                                     sorted(counts.items())), file=sys.stderr)
            if args.report:
                _report(study, c, Path(args.report), carried)
            return 1 if counts.get("failed", 0) or counts.get("cancelled", 0) else 0
    assert out is not None
    if args.from_data:
        data = load_data(study, args.from_data)
        for f in render(study, data, out):
            print(f)
        return 0
    with _client(args) as c:
        _report(study, c, out, carry(c))
    return 0


def _report(study: Study, client: Any, out: Path, carried: Optional[Carried] = None) -> None:
    data_dir = collect(study, client, out / "data", carried)
    data = load_data(study, data_dir)
    for f in render(study, data, out):
        print(f)
