"""Which job of the store is which run of a study, as foamd's engine reads both: each run's spec
resolved by foamd (ResolveSpec: the base, the study's keys and the run's point, with every
default, preset and derived value filled in) against each job's record as today's engine reads
it (Job.resolved_spec_json: keys renamed, retired or added since the job was stored read as the
engine's key table says). A job is a run when the two agree on every key but the labels (the
preset's name, the accuracy targets, which only choose the other keys' values). Also: a
[[share]]d run's jobs in the other study; a diagnosis rerun's jobs; and the rows of an
earlier store's data (a report's data folder) that a study carries over.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, FrozenSet, List, Optional, Sequence, Tuple

from activefoam.client import flatten, state_name
from activefoam.inputs import read_bounded
from activefoam.study.studyfile import (SIMULATION_FAILURES, Diagnosis, Run, Share, Study,
                                        StudyError, _same, _same_point, builtin_diagnoses)


def _base(study: Study) -> Any:
    """What a run is submitted (and resolved) on: the base spec file, or no spec (the study's
    keys say all)."""
    return study.base if study.base_text else {}


@dataclass(frozen=True)
class RunSpec:
    """A spec as foamd's engine resolved it: every key (dotted), and which of them are labels."""
    spec: Dict[str, Any]
    labels: FrozenSet[str]


# Per client (one server, one engine): the resolved specs asked for so far, by base and settings.
_RESOLVED: "weakref.WeakKeyDictionary[Any, Dict[str, RunSpec]]" = weakref.WeakKeyDictionary()


def _run_spec(study: Study, client: Any, settings: Dict[str, Any], what: str) -> RunSpec:
    """The spec foamd runs for the study's base with `settings` on top (a run's keys, or a
    diagnosis rerun's), as its engine resolves it: one ResolveSpec per distinct spec. A spec
    foamd refuses is a StudyError naming `what` and the key."""
    key = json.dumps([study.base_text, list(settings.items())])
    cache = _RESOLVED.setdefault(client, {})
    if key not in cache:
        try:
            resp = client.resolve(_base(study), overrides=settings)
        except ValueError as e:
            raise StudyError(f"{study.path}: {what}: {e}") from None
        cache[key] = RunSpec(flatten(json.loads(resp.spec_json)), frozenset(resp.labels))
    return cache[key]


@functools.lru_cache(maxsize=4096)
def _read_record(text: str) -> Dict[str, Any]:
    return flatten(json.loads(text))


def _job_spec(job: Any) -> Optional[Dict[str, Any]]:
    """A job's record as foamd's engine reads it (resolved_spec_json), by dotted key; None where
    foamd could not read it (such a job is no run)."""
    text = getattr(job, "resolved_spec_json", "")
    return _read_record(text) if text else None


_ABSENT = object()


def _differing_key(run: RunSpec, spec: Dict[str, Any]) -> Optional[str]:
    """The first key on which a resolved spec (a job's record, another study's run) is not the
    run's, labels aside; None when they are one run."""
    for k in list(run.spec) + [k for k in spec if k not in run.spec]:
        if k in run.labels:
            continue
        want, got = run.spec.get(k, _ABSENT), spec.get(k, _ABSENT)
        if want is _ABSENT or got is _ABSENT or (want is None) != (got is None):
            return k
        if want is not None and not _same(got, want):
            return k
    return None


def _is_run(study: Study, client: Any, run: Run, spec: Dict[str, Any]) -> bool:
    return _differing_key(_run_spec(study, client, study.settings(run), run.label()),
                          spec) is None


def _jobs_by_run(study: Study, client: Any, jobs: Sequence[Any]
                 ) -> Tuple[Dict[int, List[Any]], List[Any]]:
    """Run index → its jobs among `jobs`, oldest first; and those that are no run of the study
    (stale: an earlier version of the file)."""
    runs = study.runs()
    by_seed: Dict[int, List[int]] = {}
    for i, r in enumerate(runs):
        by_seed.setdefault(r.seed, []).append(i)
    found: Dict[int, List[Any]] = {}
    stale: List[Any] = []
    for j in sorted(jobs, key=lambda j: (j.created_utc, j.id)):
        spec = _job_spec(j)
        hit = None if spec is None else next(
            (i for i in by_seed.get(int(j.seed), []) if _is_run(study, client, runs[i], spec)),
            None)
        if hit is None:
            stale.append(j)
        else:
            found.setdefault(hit, []).append(j)
    return found, stale


def _share_of(study: Study, run: Run) -> Optional[Share]:
    return next((sh for sh in study.shares if sh.covers(run.point, run.seed)), None)


def _shared_run(sh: Share, run: Run) -> Optional[Tuple[int, Run]]:
    """The other study's run (its index and run) that `run` shares; None where it runs none."""
    return next(((k, r) for k, r in enumerate(sh.other.runs())
                 if r.seed == run.seed and _same_point(r.point, sh.that)), None)


def _check_one_run(study: Study, client: Any, sh: Share, run: Run, other: Run) -> None:
    """A StudyError naming the first key on which this study's run and the other study's run at
    the shared point resolve differently (a key one point leaves to the base that the other
    sets to another value): they are not one run."""
    mine = _run_spec(study, client, study.settings(run), run.label())
    theirs = _run_spec(sh.other, client, sh.other.settings(other),
                       f"{sh.other.name}'s run {other.label()}")
    key = _differing_key(mine, theirs.spec)
    if key is not None:
        raise StudyError(
            f"{study.path}: share[{sh.index}]: {key} is {mine.spec.get(key)} in this study's "
            f"run {run.label()} but {theirs.spec.get(key)} in {sh.other.name}'s run "
            f"{other.label()}: not one run")


def _owner_of_shared_run(study: Study, client: Any, run: Run
                         ) -> Optional[Tuple[Study, Run, int]]:
    """For a shared run that must be submitted: the study that owns it (the other study of its
    [[share]]), its run there and that run's jobs so far — so that it is submitted as the owner
    would submit it, and the owner finds it as its own rather than running it again. None when
    the run is not shared; a StudyError when the two are not one run."""
    sh = _share_of(study, run)
    if sh is None:
        return None
    shared = _shared_run(sh, run)
    if shared is None:
        return None
    k, other = shared
    _check_one_run(study, client, sh, run, other)
    other_jobs, _ = _jobs_by_run(sh.other, client, client.job_infos(tag=sh.other.tag))
    return sh.other, other, len(other_jobs.get(k, []))


def _shared_jobs(study: Study, client: Any, own: Dict[int, List[Any]]) -> Dict[int, List[Any]]:
    """Run index → the other study's jobs of that run, for the shared runs that have no job of
    their own: the jobs of the other study's run at the shared point, once the two runs are
    shown to be one (foamd resolves both to the same spec; else a StudyError names the key). A
    run with no job anywhere is submitted as the other study's (submit_missing). A run whose own
    jobs were all cancelled (say, submitted while the other study's were being resubmitted)
    takes the other study's jobs like a run with none."""
    runs = study.runs()
    out: Dict[int, List[Any]] = {}
    if not study.shares:
        return out
    listed: Dict[str, List[Any]] = {}
    for sh in study.shares:
        if sh.other.tag not in listed:
            listed[sh.other.tag] = client.job_infos(tag=sh.other.tag)
        other_jobs, _ = _jobs_by_run(sh.other, client, listed[sh.other.tag])
        for i, run in enumerate(runs):
            mine = own.get(i, [])
            if not sh.covers(run.point, run.seed) or any(state_name(j.state) != "cancelled"
                                                for j in mine):
                continue
            shared = _shared_run(sh, run)
            jobs = other_jobs.get(shared[0], []) if shared is not None else []
            if not jobs:
                continue
            _check_one_run(study, client, sh, run, shared[1])
            out[i] = list(jobs)
    return out


def _run_jobs(study: Study, client: Any) -> Tuple[Dict[int, List[Any]], Dict[int, str],
                                                  List[Any]]:
    """Run index → its jobs (its own, else the shared study's); run index → the study the jobs
    belong to, for shared runs; and this study's stale jobs."""
    own, stale = _jobs_by_run(study, client, client.job_infos(tag=study.tag))
    shared = _shared_jobs(study, client, own)
    found = dict(own)
    source: Dict[int, str] = {}
    for i, js in shared.items():
        found[i] = js
        source[i] = _share_of(study, study.runs()[i]).other.name
    return found, source, stale


# ---- diagnoses: reruns of failed runs with some keys changed ------------------------------------

def run_diagnoses(study: Study, client: Any, run: Run) -> List[Diagnosis]:
    """A run's diagnoses: the study file's [[diagnose]] tables, else the built-in ones of the
    run's spec as foamd resolves it (its preset, its guard's depth; builtin_diagnoses); none with
    [study] diagnose = false. A run foamd refuses is a StudyError naming it."""
    if not study.diagnose:
        return []
    if study.diagnoses:
        return list(study.diagnoses)
    return builtin_diagnoses(_run_spec(study, client, study.settings(run), run.label()).spec)


def _rerun_spec(study: Study, client: Any, run: Run, d: Diagnosis) -> Optional[RunSpec]:
    """A diagnosis rerun's resolved spec; None where foamd refuses it (no job can be its rerun:
    submitting one says why)."""
    try:
        return _run_spec(study, client, study.diag_settings(run, d),
                         f"diagnose {d.name!r} of {run.label()}")
    except StudyError:
        return None


def _diag_jobs(study: Study, client: Any) -> Dict[int, Dict[str, List[Any]]]:
    """Run index → diagnosis name → its reruns (tag diag:NAME), oldest first."""
    out: Dict[int, Dict[str, List[Any]]] = {}
    if not study.diagnose:
        return out
    runs = study.runs()
    by_seed: Dict[int, List[int]] = {}
    for i, r in enumerate(runs):
        by_seed.setdefault(r.seed, []).append(i)
    for j in sorted(client.job_infos(tag=study.diag_tag), key=lambda j: (j.created_utc, j.id)):
        spec = _job_spec(j)
        if spec is None:
            continue
        for i in by_seed.get(int(j.seed), []):
            try:
                ds = run_diagnoses(study, client, runs[i])
            except StudyError:
                continue  # a run foamd refuses has no job, nor reruns
            d = next((d for d in ds
                      if (rerun := _rerun_spec(study, client, runs[i], d)) is not None
                      and _differing_key(rerun, spec) is None), None)
            if d is not None:
                out.setdefault(i, {}).setdefault(d.name, []).append(j)
                break
    return out


def _diag_of_runs(study: Study, client: Any, source: Dict[int, str]
                  ) -> Dict[int, Dict[str, List[Any]]]:
    """Run index → diagnosis name → reruns, with a shared run's taken from the study that owns
    it (the one whose job it is: its diagnoses apply)."""
    own = _diag_jobs(study, client)
    out = {i: ds for i, ds in own.items() if i not in source}
    cache: Dict[str, Dict[int, Dict[str, List[Any]]]] = {}
    for i, run in enumerate(study.runs()):
        if i not in source:
            continue
        sh = _share_of(study, run)
        if sh is None:
            continue
        if sh.other.name not in cache:
            cache[sh.other.name] = _diag_jobs(sh.other, client)
        shared = _shared_run(sh, run)
        if shared is not None and shared[0] in cache[sh.other.name]:
            out[i] = cache[sh.other.name][shared[0]]
    return out


def _diag_is_noop(study: Study, client: Any, run: Run, d: Diagnosis, job: Any) -> bool:
    """Whether the failed job of `run` already ran as the diagnosis would rerun it: the rerun
    resolves to the job's record on every key but the labels (the values may have come from a
    preset or the defaults, which the study file does not show), so it would fail bit for bit."""
    spec = _job_spec(job)
    rerun = _rerun_spec(study, client, run, d) if spec is not None else None
    return rerun is not None and _differing_key(rerun, spec) is None


NOOP_TEXT = "not rerun: the run already had these numerics"


# ---- runs of an earlier store: a report's committed data -----------------------------------------

@dataclass
class Carried:
    """The ended runs of a report's data folder (what `collect` wrote from an earlier store):
    a study continued on another store (a new machine, a lost database) takes them as done
    instead of running them again, and reports them with the store's."""
    source: Path
    rows: Dict[int, Dict[str, Any]]   # run index → its row of runs.csv
    samples: Any                      # DataFrame: those rows' samples
    msrd: Any                         # DataFrame: those rows' MSRD curves
    curves: Any = None                # DataFrame: their other curves (curves.csv.gz), if any


def diagnosis_entries(text: Any) -> Dict[str, str]:
    """A runs.csv row's `diagnoses` ("NAME: outcome (job); …") as name → outcome; {} for an
    empty cell."""
    if not isinstance(text, str):
        return {}
    return {name: outcome for name, _, outcome in
            (e.partition(": ") for e in text.split("; ") if e)}


def unended_diagnoses(carried_text: Any) -> List[str]:
    """The diagnoses a carried row lists as queued or running: their reruns were in an earlier
    store and did not end there."""
    return [name for name, outcome in diagnosis_entries(carried_text).items()
            if outcome.startswith(("queued (", "running ("))]


def _py(v: Any) -> Any:
    """A CSV cell as the study file would write it (numpy scalars to Python, "True" to True)."""
    if hasattr(v, "item"):
        v = v.item()
    if isinstance(v, str) and v in ("True", "False"):
        return v == "True"
    return v


def carried_runs(study: Study, data_dir: os.PathLike, client: Any = None) -> Carried:
    """The runs of data_dir that ended (succeeded, or failed in the simulation itself, which
    reruns the same way): each matched to this study's run by its seed and point values. A row
    carrying the run's settings and base spec's hash (data of an older tool has neither) is taken
    only if they are this run's today: a study whose base file changed does not take the old
    runs, nor one whose keys changed the run. With a client, the row's settings are the run's
    when foamd resolves the two to the same spec on every key but the labels (a row written
    while the study file spelled out what is now the default step, or with a key an earlier
    version had, is the run of the file that leaves it to the default); without, when the two
    are the same keys and values."""
    import pandas as pd
    d = Path(data_dir)
    for f in ("runs.csv", "samples.csv.gz", "msrd.csv.gz"):
        if not (d / f).is_file():
            raise StudyError(f"--with-data: {d / f} is missing (a report's data folder holds "
                             "runs.csv, samples.csv.gz and msrd.csv.gz)")
    meta = d / "collected.json"
    if meta.is_file():
        try:
            text = read_bounded(meta, 1 << 20, "--with-data", regular=True)
        except ValueError as e:  # over 1 MiB, or not a file
            raise StudyError(str(e)) from None
        try:
            doc = json.loads(text)
        except ValueError as e:  # not JSON, not UTF-8
            raise StudyError(f"--with-data: {meta}: not JSON ({e})") from None
        name = doc.get("study") if isinstance(doc, dict) else None
        if name and name != study.name:
            raise StudyError(f"--with-data: {d} holds study {name!r}'s runs, not {study.name!r}'s")
    table = pd.read_csv(d / "runs.csv")
    runs = study.runs()
    rows: Dict[int, Dict[str, Any]] = {}
    for rec in table.to_dict("records"):
        row = {k: _py(v) for k, v in rec.items()}
        state = row.get("state")
        kind = row.get("failure_kind")
        if not (state == "succeeded" or (state == "failed" and kind in SIMULATION_FAILURES)):
            continue
        seed = row.get("seed")
        base = row.get("base_sha256")
        if seed is None or (isinstance(base, str) and base and base != _base_sha(study)):
            continue  # the base spec file changed since: another run
        settings = row.get("settings")
        then = json.loads(settings) if isinstance(settings, str) and settings else None
        # The point's columns where the row has them (a key the study varies today may have
        # been another key then: the row's settings then decide, read by foamd).
        for i, r in enumerate(runs):
            if int(seed) != r.seed or not all(
                    _same(_py(row[k]), v) for k, v in r.point.items() if k in row):
                continue
            if then is None:
                if all(k in row for k in r.point):
                    rows[i] = row
                    break
                continue
            now = study.settings(r)
            if (set(now) == set(then) and all(_same(now[k], then[k]) for k in now)) or (
                    client is not None and _same_run(study, client, r, then)):
                rows[i] = row
                break
    ids = {r["job_id"] for r in rows.values()}
    samples = pd.read_csv(d / "samples.csv.gz")
    msrd = pd.read_csv(d / "msrd.csv.gz")
    curves = pd.read_csv(d / "curves.csv.gz") if (d / "curves.csv.gz").is_file() else None
    return Carried(d, rows, samples[samples["job_id"].isin(ids)], msrd[msrd["job_id"].isin(ids)],
                   None if curves is None else curves[curves["job_id"].isin(ids)])


def _same_run(study: Study, client: Any, run: Run, settings: Dict[str, Any]) -> bool:
    """Whether settings recorded for `run` resolve to the spec the study's run does today; a
    recorded spec foamd refuses (a key retired with a value it no longer reads) is not."""
    try:
        then = _run_spec(study, client, settings, run.label())
    except StudyError:
        return False
    return _differing_key(_run_spec(study, client, study.settings(run), run.label()),
                          then.spec) is None


def _base_sha(study: Study) -> str:
    return hashlib.sha256(study.base_text.encode()).hexdigest()


def _takes_carried(have: List[Any], carried: Optional[Carried], i: int) -> bool:
    """Whether run i is the carried row's: it has no job in this store that is live or ended
    (none, or only cancelled ones)."""
    return (carried is not None and i in carried.rows and
            (not have or state_name(have[-1].state) == "cancelled"))
