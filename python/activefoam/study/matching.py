"""Which job of the store is which run of a study: by the keys the study sets, read back from
each job's resolved spec; a [[share]]d run's jobs in the other study; a [[diagnose]] rerun's
jobs; and the rows of an earlier store's data (a report's data folder) that a study carries
over.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

try:
    import tomllib  # Python >= 3.11
except ModuleNotFoundError:  # pragma: no cover - Python 3.9/3.10: the tomli package
    import tomli as tomllib  # type: ignore

from activefoam.client import flatten, state_name
from activefoam.inputs import read_bounded
from activefoam.study.studyfile import (SIMULATION_FAILURES, Diagnosis, Run, Share, Study,
                                        StudyError, _same, _same_point)


def _spec_value(spec: Dict[str, Any], key: str) -> Any:
    value: Any = spec
    for part in key.split("."):
        if not isinstance(value, dict) or part not in value:
            return None
        value = value[part]
    return value


# Spec keys added after jobs were already stored, with the value the engine ran those jobs at: a
# resolved spec from before the key does not name it, and reads as this value (else a study that
# sweeps the key could never find its reference runs among the older jobs).
KEYS_ADDED_LATER = {"numerics.contact_max_facing_deg": 90.0,
                    "numerics.contact_max_overlap_um": 0.0,
                    "numerics.remesh_on_surface": False,
                    "numerics.remesh_keep_out_um": 0.0,
                    "scene.polarity_from_preparation": False}


def _record_law(spec: Dict[str, Any]) -> Optional[str]:
    """numerics.contact_law of a job's record: its own, or what the two switches of earlier
    versions named; None for a record with neither (its integrator and step tell it apart)."""
    law = _spec_value(spec, "numerics.contact_law")
    within = _spec_value(spec, "numerics.contact_within_prisms")
    if law is not None or within is None:
        return law
    if not within:
        return "supplement"
    return "prisms-overlap" if _spec_value(spec, "numerics.contact_prisms_overlap_only") \
        else "prisms"


def _record_repair(spec: Dict[str, Any]) -> Optional[str]:
    """numerics.remesh_repair of a job's record: its own, or what the rescue and rebuild switches
    of earlier versions named; None for a record with neither."""
    repair = _spec_value(spec, "numerics.remesh_repair")
    if repair is not None:
        return repair
    if _spec_value(spec, "numerics.remesh_rescue") is None and \
            _spec_value(spec, "numerics.remesh_rebuild") is None:
        return None
    if _spec_value(spec, "numerics.remesh_rebuild"):
        return "rescue-rebuild"
    return "rescue" if _spec_value(spec, "numerics.remesh_rescue") else "none"


# The keys that replaced earlier switches, read from either kind of record; and the switches,
# read from records that name the key instead (a study file of earlier versions).
_RECORD_READERS = {
    "numerics.contact_law": _record_law,
    "numerics.remesh_repair": _record_repair,
    "numerics.contact_within_prisms": lambda s: (None if _record_law(s) is None
                                                 else _record_law(s) != "supplement"),
    "numerics.contact_prisms_overlap_only": lambda s: (None if _record_law(s) is None
                                                       else _record_law(s) == "prisms-overlap"),
    "numerics.remesh_rescue": lambda s: (None if _record_repair(s) is None
                                         else _record_repair(s) != "none"),
    "numerics.remesh_rebuild": lambda s: (None if _record_repair(s) is None
                                          else _record_repair(s) == "rescue-rebuild"),
}


def _resolved_value(spec: Dict[str, Any], key: str) -> Any:
    """A key's value in a job's resolved spec. The reduced keys are resolved into the absolute
    ones (and null there), so they are computed back: p_a r/2γ, τ_γ = η/γ, L_η/r = √(η/ξ)/r."""
    c = spec.get("cells", {})
    try:
        if key == "cells.pa_reduced":
            return c["p_a"] * c["radius_mean_um"] / (2 * c["gamma"])
        if key == "cells.tau_gamma_s":
            return c["eta"] / c["gamma"]
        if key == "cells.l_eta_reduced":
            return math.sqrt(c["eta"] / c["xi"]) / c["radius_mean_um"]
    except (KeyError, TypeError, ZeroDivisionError):
        return None
    if key == "scene" and isinstance(spec.get("scene"), dict):
        return spec["scene"].get("kind")
    if key in _RECORD_READERS:
        return _RECORD_READERS[key](spec)
    value = _spec_value(spec, key)
    if value is None and key in KEYS_ADDED_LATER and spec:
        return KEYS_ADDED_LATER[key]
    return value


# Defaults that changed after jobs were stored: a study that leaves one unset runs at today's
# default, and a stored job at the earlier value is not its run (a study whose runs were made
# before the change says `key = <earlier value>` in its [spec]).
DEFAULTS_CHANGED = {"numerics.remesh_on_surface": True,
                    "numerics.remesh_repair": "rescue-rebuild",
                    "numerics.max_volume_error": 0.2,
                    "scene.polarity_from_preparation": True}
# And the values each preset sets (docs/science/presets.md): the numerics a study that names no
# preset (standard) or names one runs at, where the defaults of earlier versions differed.
PRESET_VALUES = {
    "standard": {"numerics.integrator": "contact-implicit-consistent", "numerics.dt_s": 1.0,
                 "numerics.cg_tol": 0.01, "numerics.contact_law": "prisms-overlap"},
    "reference": {"numerics.integrator": "contact-implicit-consistent", "numerics.dt_s": 0.25,
                  "numerics.cg_tol": 0.001, "numerics.contact_law": "supplement"},
}


def _base_keys(study: Study) -> set:
    """The dotted keys the study's base spec sets (TOML or JSON; none if it is neither)."""
    if not study.base_text:
        return set()
    try:
        doc = tomllib.loads(study.base_text)
    except tomllib.TOMLDecodeError:
        # `scene = "fusion"` beside a [scene] table, as the engine reads it (the kind may be
        # written either way): the table's keys without the top-level one.
        lifted = re.sub(r'(?m)^scene\s*=.*$', "", study.base_text)
        try:
            doc = tomllib.loads(lifted)
        except tomllib.TOMLDecodeError:
            try:
                doc = json.loads(study.base_text)
            except ValueError:
                return set()
    return set(flatten(doc)) if isinstance(doc, dict) else set()


def _matches(study: Study, run: Run, spec: Dict[str, Any],
             settings: Optional[Dict[str, Any]] = None) -> bool:
    """Whether a job's resolved spec is this run's (or, with `settings`, the run with those
    keys: a diagnosis rerun)."""
    if settings is None:
        settings = study.settings(run)
    for k, v in settings.items():
        if k == "numerics.preset":
            continue  # a name: the values it chose are compared below
        got = _resolved_value(spec, k)
        if got is None:
            if k in run.point or k == "seed":
                return False
            continue  # a key the resolved spec does not echo (e.g. an alias): cannot check
        if not _same(got, v):
            return False
    preset = str(settings.get("numerics.preset", "standard"))
    for k, now in {**DEFAULTS_CHANGED, **PRESET_VALUES.get(preset, {})}.items():
        if k in settings or k in _base_keys(study):
            continue  # set by the study (checked above) or by its base spec (then both agree)
        got = _resolved_value(spec, k)
        if got is None:
            continue  # a record that does not name it (a partial one): cannot check
        if not _same(got, now):
            return False
    return True


def _jobs_by_run(study: Study, jobs: Sequence[Any]) -> Tuple[Dict[int, List[Any]], List[Any]]:
    """Run index → its jobs, oldest first; and the study's jobs that match no run (stale: an
    earlier version of the file)."""
    runs = study.runs()
    by_seed: Dict[int, List[int]] = {}
    for i, r in enumerate(runs):
        by_seed.setdefault(r.seed, []).append(i)
    found: Dict[int, List[Any]] = {}
    stale: List[Any] = []
    for j in sorted(jobs, key=lambda j: (j.created_utc, j.id)):
        spec = json.loads(j.spec_json) if j.spec_json else {}
        hit = next((i for i in by_seed.get(int(j.seed), [])
                    if _matches(study, runs[i], spec)), None)
        if hit is None:
            stale.append(j)
        else:
            found.setdefault(hit, []).append(j)
    return found, stale


def _share_of(study: Study, run: Run) -> Optional[Share]:
    return next((sh for sh in study.shares if sh.covers(run.point, run.seed)), None)


def _share_base_verified(study: Study, sh: Share, own_specs: List[Tuple[Run, Dict]]) -> bool:
    """Whether this study's own jobs show that its base gives the keys only the other study's
    point sets (sh.that, not sh.this) the values set there: False while no job shows them yet;
    an error naming the key when one differs (the two are not one run)."""
    for key in (k for k in sh.that if k not in sh.this):
        base = [_resolved_value(spec, key) for r, spec in own_specs if key not in r.point]
        base = [v for v in base if v is not None]
        if not base:
            return False
        if not _same(base[0], sh.that[key]):
            raise StudyError(
                f"{study.path}: share[{sh.index}]: {key} is {base[0]} in this study's "
                f"runs (its base) but {sh.that[key]} at the shared point of "
                f"{sh.other.name}: not one run")
    return True


def _owner_of_shared_run(study: Study, client: Any, run: Run
                         ) -> Optional[Tuple[Study, Run, int]]:
    """For a shared run that must be submitted: the study that owns it (the other study of its
    [[share]]), its run there and that run's jobs so far — so that it is submitted as the owner
    would submit it, and the owner finds it as its own rather than running it again. None when
    the run is not shared, or this study's own jobs cannot show yet that the two are one run."""
    sh = _share_of(study, run)
    if sh is None:
        return None
    own, _ = _jobs_by_run(study, client.job_infos(tag=study.tag))
    own_specs = [(study.runs()[i], json.loads(j.spec_json) if j.spec_json else {})
                 for i, js in own.items() for j in js]
    if not _share_base_verified(study, sh, own_specs):
        return None
    other_runs = sh.other.runs()
    k = next((k for k, r in enumerate(other_runs)
              if r.seed == run.seed and _same_point(r.point, sh.that)), None)
    if k is None:
        return None
    other_jobs, _ = _jobs_by_run(sh.other, client.job_infos(tag=sh.other.tag))
    return sh.other, other_runs[k], len(other_jobs.get(k, []))


def _shared_jobs(study: Study, client: Any, own: Dict[int, List[Any]]) -> Dict[int, List[Any]]:
    """Run index → the other study's jobs of that run, for the shared runs that have no job of
    their own. A job is taken only when its resolved spec shows it is this run: this study's
    keys (the point, the seed, [spec]) have their values in it, and the keys only the other
    point sets have, in this study's own jobs, the values the base gives them. Until this study
    has a job of its own to read the base from, nothing is shared (the run is submitted as this
    study's own). A run with no job anywhere is submitted as the other study's (submit_missing). A run
    whose own jobs were all cancelled (say, submitted while the other study's were being
    resubmitted) takes the other study's jobs like a run with none."""
    runs = study.runs()
    out: Dict[int, List[Any]] = {}
    if not study.shares:
        return out
    own_specs = [(runs[i], json.loads(j.spec_json) if j.spec_json else {})
                 for i, js in own.items() for j in js]
    listed: Dict[str, List[Any]] = {}
    for sh in study.shares:
        if sh.other.tag not in listed:
            listed[sh.other.tag] = client.job_infos(tag=sh.other.tag)
        other_jobs, _ = _jobs_by_run(sh.other, listed[sh.other.tag])
        other_runs = sh.other.runs()
        for i, run in enumerate(runs):
            mine = own.get(i, [])
            if not sh.covers(run.point, run.seed) or any(state_name(j.state) != "cancelled"
                                                for j in mine):
                continue
            k_other = next((k for k, r in enumerate(other_runs)
                            if r.seed == run.seed and _same_point(r.point, sh.that)), None)
            jobs = other_jobs.get(k_other, []) if k_other is not None else []
            if not jobs or not _share_base_verified(study, sh, own_specs):
                continue
            for j in jobs:
                spec = json.loads(j.spec_json) if j.spec_json else {}
                if not _matches(study, run, spec):
                    bad = next((k for k, v in study.settings(run).items()
                                if (_resolved_value(spec, k) is None and k in run.point)
                                or (_resolved_value(spec, k) is not None
                                    and not _same(_resolved_value(spec, k), v))), "?")
                    raise StudyError(
                        f"{study.path}: share[{sh.index}]: job {j.id} of {sh.other.name} has "
                        f"{bad} = {_resolved_value(spec, bad)}, this run sets "
                        f"{study.settings(run).get(bad)}: not one run")
            out[i] = list(jobs)
    return out


def _run_jobs(study: Study, client: Any) -> Tuple[Dict[int, List[Any]], Dict[int, str],
                                                  List[Any]]:
    """Run index → its jobs (its own, else the shared study's); run index → the study the jobs
    belong to, for shared runs; and this study's stale jobs."""
    own, stale = _jobs_by_run(study, client.job_infos(tag=study.tag))
    shared = _shared_jobs(study, client, own)
    found = dict(own)
    source: Dict[int, str] = {}
    for i, js in shared.items():
        found[i] = js
        source[i] = _share_of(study, study.runs()[i]).other.name
    return found, source, stale


# ---- diagnoses: reruns of failed runs with some keys changed ------------------------------------

def _diag_jobs(study: Study, client: Any) -> Dict[int, Dict[str, List[Any]]]:
    """Run index → diagnosis name → its reruns (tag diag:NAME), oldest first."""
    out: Dict[int, Dict[str, List[Any]]] = {}
    if not study.diagnoses:
        return out
    runs = study.runs()
    by_seed: Dict[int, List[int]] = {}
    for i, r in enumerate(runs):
        by_seed.setdefault(r.seed, []).append(i)
    for j in sorted(client.job_infos(tag=study.diag_tag), key=lambda j: (j.created_utc, j.id)):
        spec = json.loads(j.spec_json) if j.spec_json else {}
        for i in by_seed.get(int(j.seed), []):
            d = next((d for d in study.diagnoses
                      if _matches(study, runs[i], spec, study.diag_settings(runs[i], d))), None)
            if d is not None:
                out.setdefault(i, {}).setdefault(d.name, []).append(j)
                break
    return out


def _diag_of_runs(study: Study, client: Any, source: Dict[int, str]
                  ) -> Dict[int, Dict[str, List[Any]]]:
    """Run index → diagnosis name → reruns, with a shared run's taken from the study that owns
    it (the one whose job it is: its [[diagnose]] tables apply)."""
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
        k = next((k for k, r in enumerate(sh.other.runs())
                  if r.seed == run.seed and _same_point(r.point, sh.that)), None)
        if k is not None and k in cache[sh.other.name]:
            out[i] = cache[sh.other.name][k]
    return out


def _diag_is_noop(d: Diagnosis, job: Any) -> bool:
    """Whether the failed job already ran with every value the diagnosis sets (from a preset or
    the defaults, which the study file does not show): its rerun would be the same run."""
    spec = json.loads(job.spec_json) if getattr(job, "spec_json", "") else {}
    if not spec:
        return False
    for k, v in d.spec.items():
        got = _resolved_value(spec, k)
        if got is None or not _same(got, v):
            return False
    return True


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


def _py(v: Any) -> Any:
    """A CSV cell as the study file would write it (numpy scalars to Python, "True" to True)."""
    if hasattr(v, "item"):
        v = v.item()
    if isinstance(v, str) and v in ("True", "False"):
        return v == "True"
    return v


def carried_runs(study: Study, data_dir: os.PathLike) -> Carried:
    """The runs of data_dir that ended (succeeded, or failed in the simulation itself, which
    reruns the same way): each matched to this study's run by its seed and point values. A row
    carrying the run's settings and base spec's hash (data of an older tool has neither) is taken
    only if they are this run's today: a study whose [spec] or base file changed does not take the
    old runs."""
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
        hit = next((i for i, r in enumerate(runs)
                    if seed is not None and int(seed) == r.seed and
                    all(k in row and _same(_py(row[k]), v) for k, v in r.point.items())), None)
        if hit is None:
            continue
        settings = row.get("settings")
        if isinstance(settings, str) and settings:
            now = study.settings(runs[hit])
            then = json.loads(settings)
            if set(now) != set(then) or not all(_same(now[k], then[k]) for k in now):
                continue
        base = row.get("base_sha256")
        if isinstance(base, str) and base and base != _base_sha(study):
            continue  # the base spec file changed since: another run
        rows[hit] = row
    ids = {r["job_id"] for r in rows.values()}
    samples = pd.read_csv(d / "samples.csv.gz")
    msrd = pd.read_csv(d / "msrd.csv.gz")
    return Carried(d, rows, samples[samples["job_id"].isin(ids)], msrd[msrd["job_id"].isin(ids)])


def _base_sha(study: Study) -> str:
    return hashlib.sha256(study.base_text.encode()).hexdigest()


def _takes_carried(have: List[Any], carried: Optional[Carried], i: int) -> bool:
    """Whether run i is the carried row's: it has no job in this store that is live or ended
    (none, or only cancelled ones)."""
    return (carried is not None and i in carried.rows and
            (not have or state_name(have[-1].state) == "cancelled"))
