"""Submitting a study's missing runs to foamd (each exactly once: an idempotency key per run and
attempt), its diagnosis reruns, cancelling the jobs of an earlier version of the file, and
waiting with a progress line until every run has ended.
"""

from __future__ import annotations

import sys
import time
from typing import Any, Collection, Dict, List, Optional, Tuple, Union

from activefoam.client import state_name
from activefoam.study.matching import (NOOP_TEXT, Carried, _base, _diag_is_noop, _diag_jobs,
                                       _jobs_by_run, _owner_of_shared_run, _run_jobs,
                                       _takes_carried, run_diagnoses, unended_diagnoses)
from activefoam.study.studyfile import MAX_ATTEMPTS, SIMULATION_FAILURES, Study, StudyError


def _retries(retry_failed: Union[bool, Collection[str]], kind: str) -> bool:
    """Whether `--retry-failed` (True: every kind) or `--retry-kinds` (a set) reruns a failure of
    `kind`: after a fix that changes only runs that failed so (a preparation that now follows
    the run's volume limit), the runs of that kind are rerun and the others' results stand."""
    if isinstance(retry_failed, bool):
        return retry_failed
    return kind in retry_failed


def _retry_kinds(arg: Optional[str]) -> Union[bool, Collection[str]]:
    """`--retry-kinds` as given: absent → False, KINDS → that set (checked)."""
    if arg is None:
        return False
    kinds = {k.strip() for k in arg.split(",") if k.strip()}
    unknown = sorted(kinds - SIMULATION_FAILURES)
    if unknown or not kinds:
        raise StudyError(f"--retry-kinds: {', '.join(unknown) or repr(arg)} is no failure kind "
                         f"of the simulation; allowed: {', '.join(sorted(SIMULATION_FAILURES))}")
    return kinds


def _needs_job(jobs: List[Any], retry_failed: Union[bool, Collection[str]]) -> bool:
    if not jobs:
        return True
    last = jobs[-1]
    state = state_name(last.state)
    if state == "cancelled":
        return True
    if state == "failed":
        return (_retries(retry_failed, last.failure_kind) or
                last.failure_kind not in SIMULATION_FAILURES)
    return False


def _diag_needed(jobs: List[Any]) -> bool:
    """A diagnosis is run once: a rerun queued, running, ended or cancelled (by hand: a
    decision) stands; one that failed outside the simulation (an engine error, a lost worker) is
    submitted again."""
    if not jobs:
        return True
    last = jobs[-1]
    return state_name(last.state) == "failed" and last.failure_kind not in SIMULATION_FAILURES


def submit_diagnoses(study: Study, client: Any, out=sys.stderr,
                     carried: Optional[Carried] = None) -> int:
    """Submits the diagnosis reruns of the study's own runs that failed in the simulation with a
    kind one of their diagnoses names (run_diagnoses) and have no rerun yet; returns how many.
    A carried failure (an earlier store's, `carried`) gets the reruns its row lists as queued or
    running there: they did not end, and that store is not this one."""
    if not study.diagnose:
        return 0
    found, source, _ = _run_jobs(study, client)
    diag = _diag_jobs(study, client)
    runs = study.runs()
    n = 0
    for i, run in enumerate(runs):
        have = found.get(i, [])
        if i in source:
            continue  # a shared run is diagnosed by the study that owns it
        last, unended = None, None
        if _takes_carried(have, carried, i):
            row = carried.rows[i]
            if isinstance(row.get("shared_from"), str) and row["shared_from"]:
                continue
            kind, state = row.get("failure_kind"), row.get("state")
            unended = unended_diagnoses(row.get("diagnoses"))
        elif have:
            last = have[-1]
            kind, state = last.failure_kind, state_name(last.state)
        else:
            continue
        if state != "failed" or kind not in SIMULATION_FAILURES:
            continue
        for d in run_diagnoses(study, client, run):
            if kind not in d.kinds or (unended is not None and d.name not in unended):
                continue  # of a carried failure, a rerun that ended there (or none) stands
            jobs = diag.get(i, {}).get(d.name, [])
            if not _diag_needed(jobs):
                continue
            if last is not None and _diag_is_noop(study, client, run, d, last):
                print(f"study {study.name}: {run.label()} failed ({kind}): "
                      f"diagnosis {d.name!r} {NOOP_TEXT} ({', '.join(d.spec)}): "
                      + ("the study file's [[diagnose]] needs other values" if study.diagnoses
                         else "a [[diagnose]] table of the study file can name others"),
                      file=out)
                continue
            try:
                job = client.submit(
                    _base(study), overrides=study.diag_settings(run, d), tags=[study.diag_tag],
                    priority=study.priority - 1,  # after the study's own runs
                    idempotency_key=f"{study.diag_tag}:{d.name}:{study.run_id(run)}:{len(jobs)}")
            except ValueError as e:
                raise StudyError(f"{study.path}: diagnose {d.name!r} of {run.label()}: {e}"
                                 ) from None
            if job.created:
                n += 1
                print(f"study {study.name}: {run.label()} failed ({kind}): "
                      f"diagnosis {d.name!r} submitted", file=out)
    return n


def live_stale_jobs(study: Study, client: Any) -> List[Any]:
    """The study's queued or running jobs that are no run of the file as it is now (an earlier
    version's: a changed [spec], grid or seed list). They would go on and take the machine."""
    _, stale = _jobs_by_run(study, client, client.job_infos(tag=study.tag))
    return [j for j in stale if state_name(j.state) in ("queued", "running")]


def cancel_stale(study: Study, client: Any, cancel: bool, out=sys.stderr) -> int:
    """Names the live stale jobs; with `cancel`, cancels them. Returns how many there are."""
    live = live_stale_jobs(study, client)
    if not live:
        return 0
    ids = ", ".join(j.id for j in live[:8]) + (f" and {len(live) - 8} more" if len(live) > 8
                                                else "")
    if not cancel:
        print(f"study {study.name}: {len(live)} queued or running jobs of tag {study.tag} are no "
              f"run of {study.path.name} as it is now ({ids}): they go on; --cancel-stale "
              "cancels them", file=out)
        return len(live)
    # A running job may finish its last step before the cancel reaches it: the count says what
    # the server answered, not what was asked.
    states = [client.cancel(j.id, f"study {study.name}: no run of the study file as it is now")
              for j in live]
    stopping = sum(s == "running" for s in states)
    cancelled = sum(s == "cancelled" for s in states)
    ended = len(states) - stopping - cancelled
    print(f"study {study.name}: cancelled {cancelled + stopping} jobs that are no run of "
          f"{study.path.name} as it is now ({ids})"
          + (f"; {stopping} of them running, to stop at their next step unless it is their last"
             if stopping else "")
          + (f"; {ended} had ended before the cancel reached them" if ended else ""), file=out)
    return len(live)


def submit_missing(study: Study, client: Any,
                   retry_failed: Union[bool, Collection[str]] = False,
                   out=sys.stderr, carried: Optional[Carried] = None) -> Tuple[int, int]:
    """Submits every run that has no live or finished job; returns (submitted, already held).
    Nothing is submitted twice: each job carries an idempotency key made of the run and its
    attempt number. A run that `carried` (an earlier store's data) holds as ended counts as held
    (a failed one is submitted again with retry_failed: True, or a set of failure kinds). A
    spec foamd refuses, or a shared run that is not the other study's run, stops the submission
    and cancels what this call submitted (a study is submitted whole or not at all), then raises
    StudyError."""
    submitted: List[str] = []
    held = 0
    found, _, _ = _run_jobs(study, client)
    for i, run in enumerate(study.runs()):
        have = found.get(i, [])
        if not _needs_job(have, retry_failed):
            held += 1
            continue
        if _takes_carried(have, carried, i) and not (
                carried.rows[i]["state"] == "failed" and
                _retries(retry_failed, str(carried.rows[i].get("failure_kind") or ""))):
            held += 1
            continue
        failed = sum(1 for j in have if state_name(j.state) == "failed")
        if failed >= MAX_ATTEMPTS:
            print(f"study {study.name}: {run.label()}: {failed} attempts failed; not "
                  "submitted again", file=out)
            held += 1
            continue
        try:
            # A shared run is submitted as its owner's run (the same base, [spec] and preset, by
            # the share's rules), whichever study is submitted first: then the owner finds it as
            # its own, and the idempotency key is the one the owner would use.
            owner, owner_run, attempts = study, run, len(have)
            owned = _owner_of_shared_run(study, client, run)
            if owned is not None:
                owner, owner_run, attempts = owned
                print(f"study {study.name}: {run.label()} is {owner.name}'s run "
                      f"{owner_run.label()} (shared): submitted as {owner.name}'s", file=out)
            job = client.submit(
                _base(owner), overrides=owner.settings(owner_run), tags=[owner.tag],
                priority=owner.priority,
                idempotency_key=f"{owner.tag}:{owner.run_id(owner_run)}:{attempts}")
        except ValueError as e:  # refused by foamd, or a share that is not one run
            for jid in submitted:
                try:
                    client.cancel(jid, f"study {study.name}: submission aborted ({run.label()} "
                                       "was refused)")
                except Exception:  # noqa: BLE001 - best effort; the error below matters
                    pass
            if isinstance(e, StudyError):
                raise
            raise StudyError(f"{study.path}: {run.label()}: {e}") from None
        if job.created:
            submitted.append(job.id)
        else:
            held += 1
    return len(submitted), held


def _progress(study: Study, client: Any, carried: Optional[Carried] = None
              ) -> Tuple[Dict[str, int], float, List[Any]]:
    found, _, _ = _run_jobs(study, client)
    counts: Dict[str, int] = {}
    done_fraction = 0.0
    latest = []
    for i in range(len(study.runs())):
        have = found.get(i, [])
        if _takes_carried(have, carried, i):
            s = carried.rows[i]["state"]
            counts[s] = counts.get(s, 0) + 1
            done_fraction += 1.0
            continue
        if not have:
            counts["missing"] = counts.get("missing", 0) + 1
            continue
        j = have[-1]
        latest.append(j)
        s = state_name(j.state)
        counts[s] = counts.get(s, 0) + 1
        done_fraction += 1.0 if s in ("succeeded", "failed", "cancelled") else j.progress
    return counts, done_fraction, latest


def wait(study: Study, client: Any, poll_s: float = 2.0, progress: bool = True,
         timeout_s: Optional[float] = None, carried: Optional[Carried] = None) -> Dict[str, int]:
    """Waits until every run's job has ended; a progress line on stderr (tqdm where installed)."""
    n = len(study.runs())
    start = time.monotonic()
    first_fraction = None
    bar = None
    if progress:
        try:
            from tqdm import tqdm  # Debian's python3-tqdm, where installed
            bar = tqdm(total=n, unit="run", desc=f"study {study.name}", file=sys.stderr)
        except ImportError:
            bar = None
    try:
        while True:
            counts, frac, _ = _progress(study, client, carried)
            ended = sum(counts.get(s, 0) for s in ("succeeded", "failed", "cancelled"))
            if first_fraction is None:
                first_fraction = frac
            if progress:
                parts = ", ".join(f"{c} {s}" for s, c in sorted(counts.items()))
                elapsed = time.monotonic() - start
                eta = ""
                if frac > first_fraction + 1e-6 and frac < n:
                    eta = f", ETA {_hms((n - frac) * elapsed / (frac - first_fraction))}"
                if bar is not None:
                    bar.n = round(frac, 2)
                    bar.set_postfix_str(parts)
                    bar.refresh()
                else:
                    width = 24
                    filled = int(width * frac / n) if n else width
                    print(f"\rstudy {study.name}: [{'#' * filled}{'.' * (width - filled)}] "
                          f"{ended}/{n} ended ({parts}){eta}   ", end="", file=sys.stderr,
                          flush=True)
            if ended + counts.get("missing", 0) >= n:
                return counts
            if timeout_s is not None and time.monotonic() - start > timeout_s:
                raise TimeoutError(f"study {study.name}: {ended} of {n} runs ended after "
                                   f"{timeout_s} s")
            time.sleep(poll_s)
    finally:
        if bar is not None:
            bar.close()
        elif progress:
            print(file=sys.stderr)


def _hms(s: float) -> str:
    s = int(max(0, s))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"
