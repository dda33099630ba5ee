"""Studies as files: a TOML study (base spec, grids, seeds, preset) run through foamd, resumably,
and reported from the store alone (docs/science/README.md has the format and the commands).

    python3 -m activefoam.study run studies/fig14-reduced.toml      # submit what is missing, wait
    python3 -m activefoam.study report studies/fig14-reduced.toml   # figure + tables from the store
    python3 -m activefoam.study report FILE --from-data DIR          # ... from committed data
    python3 -m activefoam.study run|report FILE --with-data DIR      # store + an earlier one's data
    python3 -m activefoam.study save-store DIR | restore-store DIR   # carry a store across machines

A run of a study is one (grid point, seed). Its jobs carry the tag `study:NAME`; a job belongs to
a run when every key the study sets (its [spec] table, the point's keys, the seed, the preset)
has that value in the job's resolved spec, so rerunning `run` submits only the runs that have no
job yet, or whose job was cancelled or failed for a reason other than the simulation itself (an
engine error, a lost worker). A run that failed in the simulation (non-finite, volume drift,
interpenetration, ...) is a result — the supplement's hatched cells — and is not run again unless
`--retry-failed` (`--retry-kinds preparation-failed`: only the runs that failed so). A job of
the study that is no run of the file as it is now (an earlier version's [spec], grid or seeds)
is named when it is queued or running, and cancelled with
`--cancel-stale`. A run that failed in the simulation is rerun once per [[diagnose]] table of
the file that names its failure kind, with that table's keys changed (tag `diag:NAME`): the
report says whether the rerun ran past the failure (then the failure is those numerics', not
the point's, and the verdict table's `failed` leaves it out). Exit codes: 0 done, 1 some runs failed, 2 bad study file or spec, 3 foamd
unreachable, 4 token refused, 130 interrupted (the jobs go on in foamd; rerun to follow them).
"""

from __future__ import annotations

import argparse
import difflib
import hashlib
import json
import math
import os
import re
import sys
import textwrap
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Collection, Dict, List, Optional, Sequence, Tuple, Union

try:
    import tomllib  # Python ≥ 3.11
except ModuleNotFoundError:  # pragma: no cover - Python 3.9/3.10 with tomli installed
    import tomli as tomllib  # type: ignore

from activefoam import trends
from activefoam.client import _flatten

# Failure kinds of the simulation itself (engine/include/activefoam/run.h): deterministic for a
# (spec, seed), so a result, not something to run again.
SIMULATION_FAILURES = {"non-finite", "cg-not-converged", "inverted-triangle", "volume-drift",
                       "interpenetration", "contact-oscillation", "preparation-failed",
                       "step-error"}
MAX_RUNS = 2000          # runs (points × seeds) one study may hold
# Failed jobs per run before a run counts as failed for good. Cancelled jobs are no failed
# attempts: a study moved to another step, or a queue reordered, cancels queued jobs, and the
# run must still be submitted again (each job keeps its own idempotency key).
MAX_ATTEMPTS = 5

STUDY_KEYS = {"name", "title", "base", "preset", "seeds", "x", "x_label", "x_log", "by",
              "by_label", "priority", "scale"}
FITNESS_KEYS = {"key", "reference", "metrics"}
TOP_KEYS = {"study", "spec", "grid", "fitness", "share", "diagnose"}
DIAGNOSE_KEYS = {"name", "title", "spec", "kinds"}
SHARE_KEYS = {"file", "this", "that", "seeds"}
PRESETS = {"draft", "standard", "reference"}

# Per-run metrics of a fusion study: name → (label, where it comes from).
METRICS = {
    "theta_end_deg": "θ at the end (°)",
    "theta_last_hour_deg": "θ, mean over the last hour (°)",
    "theta_eq_deg": "θ_eq, Eq. 1 (°)",
    "tau_f_s": "τ_f, Eq. 1 (s)",
    "tau_f_over_tau_p": "τ_f / τ_p",
    "shape_index_end": "shape index at the end",
    "shape_index_last_hour": "shape index, mean over the last hour",
    "msrd_end_over_r2": "MSRD at the end / r²",
    "unique_contacts_end": "unique contacts (normalised)",
    "mixing_time_s": "mixing time (s, capped at the run)",
    "mixing_time_less_rotation_s": "mixing time less the aggregate's turn (s, capped)",
}
# Metrics that only runs of a newer engine report (its final values): a study's tables show them
# only where some run has one. The MSRD less the aggregate's rigid turn (engine tree after
# 3edd4479): near the jam a doublet turning as a body passes r² with no cell changing its
# neighbours (docs/science/jam-day).
OPTIONAL_METRICS = {"mixing_time_less_rotation_s"}


def shown_metrics(runs: Any, metrics: Sequence[str] = tuple(METRICS)) -> List[str]:
    """METRICS less the optional ones that no run of `runs` has."""
    import numpy as np
    return [m for m in metrics if m not in OPTIONAL_METRICS
            or (m in runs and bool(np.isfinite(np.asarray(runs[m], dtype=float)).any()))]
FITNESS_METRICS = ["theta_end_deg", "theta_last_hour_deg", "shape_index_end",
                   "shape_index_last_hour", "msrd_end_over_r2", "unique_contacts_end",
                   "theta_eq_deg", "tau_f_s"]
SAMPLE_COLUMNS = ["theta_deg", "shape_index_mean", "unique_contacts_norm", "neck_radius_um",
                  "volume_error_max"]


class StudyError(ValueError):
    """A bad study file: names the key and what is allowed."""


# ---- the study file ----------------------------------------------------------------------------

def _closest(word: str, known: Sequence[str]) -> str:
    m = difflib.get_close_matches(word, list(known), n=1)
    return f" (did you mean {m[0]!r}?)" if m else ""


def _unknown(keys, known, where: str) -> None:
    for k in keys:
        if k not in known:
            raise StudyError(f"{where}{k}: unknown key{_closest(k, sorted(known))}; known: "
                             f"{', '.join(sorted(known))}")


def _scalar(key: str, v: Any) -> Any:
    if isinstance(v, (bool, int, float, str)):
        if isinstance(v, float) and not math.isfinite(v):
            raise StudyError(f"{key}: {v} is not a finite number")
        return v
    raise StudyError(f"{key}: a number, string or boolean, not {type(v).__name__}")


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, bool) or isinstance(b, bool):
        return a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return a == b or abs(a - b) <= 1e-9 * max(abs(a), abs(b))
    return str(a) == str(b)


@dataclass
class Run:
    point: Dict[str, Any]
    seed: int

    def label(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in self.point.items()) + f", seed {self.seed}"


@dataclass
class Share:
    """A point this study has in common with another study (same base, [spec] and preset): its
    runs take that study's jobs at `that` point instead of running again — at every seed, or
    at `seeds` only (a point whose first seeds are one study's runs and a later seed another's:
    the studies sharing it ran different seed lists)."""
    other: "Study"
    this: Dict[str, Any]
    that: Dict[str, Any]
    index: int
    seeds: Optional[List[int]] = None

    def covers(self, point: Dict[str, Any], seed: Optional[int] = None) -> bool:
        """Whether this share holds the point (at `seed`, when given)."""
        return _same_point(point, self.this) and (
            seed is None or self.seeds is None or seed in self.seeds)

    def overlaps(self, other: "Share") -> bool:
        """Whether the two shares claim one run: the same point at a seed both cover."""
        if not _same_point(self.this, other.this):
            return False
        if self.seeds is None or other.seeds is None:
            return True
        return bool(set(self.seeds) & set(other.seeds))


@dataclass
class Diagnosis:
    """[[diagnose]]: a run that failed in the simulation with one of `kinds` is rerun once with
    `spec`'s keys set on top of its own (a reference step, a remesher fix): a rerun that runs
    to the end says the failure was those numerics', not the point's."""
    name: str
    spec: Dict[str, Any]
    kinds: List[str]
    title: str = ""


def _same_point(a: Dict[str, Any], b: Dict[str, Any]) -> bool:
    return set(a) == set(b) and all(_same(a[k], b[k]) for k in a)


@dataclass
class Study:
    path: Path
    name: str
    title: str
    seeds: List[int]
    grids: List[Dict[str, List[Any]]]
    spec: Dict[str, Any] = field(default_factory=dict)      # flat keys on top of the base file
    base: Optional[Path] = None
    base_text: str = ""
    preset: str = ""
    x: str = ""
    x_label: str = ""
    x_log: bool = False
    by: str = ""
    by_label: str = ""
    priority: int = 0
    scale: str = ""
    fitness: Optional[Dict[str, Any]] = None
    shares: List["Share"] = field(default_factory=list)
    diagnoses: List[Diagnosis] = field(default_factory=list)

    @property
    def tag(self) -> str:
        return f"study:{self.name}"

    @property
    def diag_tag(self) -> str:
        return f"diag:{self.name}"

    def diag_settings(self, run: Run, d: Diagnosis) -> Dict[str, Any]:
        """A diagnosis rerun's keys: the run's, with the diagnosis's on top."""
        return {**self.settings(run), **d.spec}

    def points(self) -> List[Dict[str, Any]]:
        """The union of the grids' cartesian products, in file order, without repeats."""
        out: List[Dict[str, Any]] = []
        seen = set()
        for g in self.grids:
            keys = list(g)
            combos: List[Dict[str, Any]] = [{}]
            for k in keys:
                combos = [{**c, k: v} for c in combos for v in g[k]]
            for c in combos:
                ident = json.dumps(c, sort_keys=True)
                if ident not in seen:
                    seen.add(ident)
                    out.append(c)
        return out

    def runs(self) -> List[Run]:
        """Seed by seed: a study cut short holds every point at its first seeds."""
        return [Run(p, s) for s in self.seeds for p in self.points()]

    def settings(self, run: Run) -> Dict[str, Any]:
        """Every key this study sets for a run, in the order they apply (later wins)."""
        out: Dict[str, Any] = {}
        if self.preset:
            out["numerics.preset"] = self.preset
        out.update(self.spec)
        out.update(run.point)
        out["seed"] = run.seed
        return out

    def run_id(self, run: Run) -> str:
        text = json.dumps({"base": self.base_text, "settings": self.settings(run)},
                          sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:20]

    def swept_keys(self) -> List[str]:
        keys: List[str] = []
        for g in self.grids:
            keys += [k for k in g if k not in keys]
        return keys


def load(path: os.PathLike, _shares: bool = True) -> Study:
    """Reads and checks a study file; StudyError names the key."""
    p = Path(path)
    if not p.is_file():
        raise StudyError(f"study: no such file {str(p)!r}")
    if p.stat().st_size > 1 << 20:
        raise StudyError(f"study: {str(p)!r} is larger than 1 MiB")
    try:
        doc = tomllib.loads(p.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise StudyError(f"study: {p}: not TOML: {e}") from None
    _unknown(doc, TOP_KEYS, "")
    st = doc.get("study")
    if not isinstance(st, dict):
        raise StudyError("study: the file needs a [study] table (name, seeds, ...)")
    _unknown(st, STUDY_KEYS, "study.")
    name = st.get("name")
    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9._-]{1,64}", name):
        raise StudyError("study.name: 1 to 64 characters of A-Z a-z 0-9 . _ - (the jobs' tag is "
                         f"study:NAME), got {name!r}")
    seeds = st.get("seeds")
    if (not isinstance(seeds, list) or not seeds or len(seeds) > 1000 or
            not all(isinstance(s, int) and not isinstance(s, bool) and 0 <= s < 2**31
                    for s in seeds)):
        raise StudyError(f"study.seeds: a list of 1 to 1000 integers in [0, 2^31), got {seeds!r}")
    if len(set(seeds)) != len(seeds):
        raise StudyError(f"study.seeds: repeated seeds in {seeds!r}")
    preset = st.get("preset", "")
    if preset and preset not in PRESETS:
        raise StudyError(f"study.preset: one of {', '.join(sorted(PRESETS))}, got {preset!r}")
    study = Study(path=p, name=name, title=str(st.get("title", name)), seeds=list(seeds),
                  grids=[], preset=preset, scale=str(st.get("scale", "")))
    for key in ("x", "by", "x_label", "by_label"):
        v = st.get(key, "")
        if not isinstance(v, str):
            raise StudyError(f"study.{key}: a string, got {v!r}")
        setattr(study, key, v)
    if not isinstance(st.get("x_log", False), bool):
        raise StudyError(f"study.x_log: true or false, got {st.get('x_log')!r}")
    study.x_log = st.get("x_log", False)
    prio = st.get("priority", 0)
    if not isinstance(prio, int) or isinstance(prio, bool) or not -1000 <= prio <= 1000:
        raise StudyError(f"study.priority: an integer in [-1000, 1000], got {prio!r}")
    study.priority = prio
    if "base" in st:
        if not isinstance(st["base"], str):
            raise StudyError(f"study.base: the path of a spec file, got {st['base']!r}")
        base = (p.parent / st["base"]).resolve()
        if not base.is_file():
            raise StudyError(f"study.base: no such spec file {str(base)!r} (relative to the "
                             "study file)")
        study.base, study.base_text = base, base.read_text()
    spec = doc.get("spec", {})
    if not isinstance(spec, dict):
        raise StudyError("spec: a table of spec keys")
    study.spec = {k: _scalar(f"spec.{k}", v) for k, v in _flatten(spec).items()}
    if "seed" in study.spec:
        raise StudyError("spec.seed: seeds belong in study.seeds")
    if not study.base_text and "scene" not in study.spec:
        raise StudyError("spec.scene: a study needs study.base (a spec file) or spec.scene")
    grids = doc.get("grid", [])
    if isinstance(grids, dict):
        grids = [grids]
    if not isinstance(grids, list) or not grids:
        raise StudyError("grid: at least one [[grid]] table of KEY = [values]")
    for i, g in enumerate(grids):
        if not isinstance(g, dict) or not g:
            raise StudyError(f"grid[{i}]: a table of KEY = [values], got {g!r}")
        flat = _flatten(g)
        for k, vs in flat.items():
            if k == "seed":
                raise StudyError(f"grid[{i}].seed: seeds belong in study.seeds")
            if not isinstance(vs, list) or not vs:
                raise StudyError(f"grid[{i}].{k}: a non-empty list of values, got {vs!r}")
            flat[k] = [_scalar(f"grid[{i}].{k}", v) for v in vs]
        study.grids.append(flat)
    swept = study.swept_keys()
    for key in ("x", "by"):
        v = getattr(study, key)
        if v and v not in swept:
            raise StudyError(f"study.{key}: {v!r} is not a grid key{_closest(v, swept)}; grid "
                             f"keys: {', '.join(swept)}")
    n = len(study.runs())
    if n > MAX_RUNS:
        raise StudyError(f"grid: {n} runs (points × seeds), more than the {MAX_RUNS} a study may "
                         "hold: split it")
    if "fitness" in doc:
        f = doc["fitness"]
        if not isinstance(f, dict):
            raise StudyError("fitness: a table (key, reference, metrics)")
        _unknown(f, FITNESS_KEYS, "fitness.")
        if f.get("key") not in swept:
            raise StudyError(f"fitness.key: a grid key (the setting compared), got "
                             f"{f.get('key')!r}; grid keys: {', '.join(swept)}")
        values = [v for g in study.grids for v in g.get(f["key"], [])]
        if "reference" not in f or not any(_same(f["reference"], v) for v in values):
            raise StudyError(f"fitness.reference: one of the values of {f['key']} "
                             f"({values}), got {f.get('reference')!r}")
        metrics = f.get("metrics", FITNESS_METRICS)
        if not isinstance(metrics, list) or not all(m in METRICS for m in metrics):
            bad = [m for m in metrics if m not in METRICS] if isinstance(metrics, list) else []
            raise StudyError(f"fitness.metrics: names among {', '.join(METRICS)}"
                             + (f"; unknown {bad[0]!r}{_closest(bad[0], list(METRICS))}"
                                if bad else ""))
        study.fitness = {"key": f["key"], "reference": f["reference"], "metrics": metrics}
    diagnoses = doc.get("diagnose", [])
    if not isinstance(diagnoses, list):
        raise StudyError("diagnose: [[diagnose]] tables (name, spec, kinds)")
    for i, d in enumerate(diagnoses):
        study.diagnoses.append(_load_diagnosis(study, i, d))
    shares = doc.get("share", [])
    if not isinstance(shares, list):
        raise StudyError("share: [[share]] tables (file, this, that)")
    if _shares:
        for i, sh in enumerate(shares):
            study.shares.append(_load_share(study, i, sh))
    return study


def _load_diagnosis(study: Study, i: int, d: Any) -> Diagnosis:
    where = f"diagnose[{i}]"
    if not isinstance(d, dict):
        raise StudyError(f"{where}: a table (name, spec, kinds), got {d!r}")
    _unknown(d, DIAGNOSE_KEYS, f"{where}.")
    name = d.get("name")
    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9._-]{1,32}", name):
        raise StudyError(f"{where}.name: 1 to 32 characters of A-Z a-z 0-9 . _ -, got {name!r}")
    if any(x.name == name for x in study.diagnoses):
        raise StudyError(f"{where}.name: {name!r} names an earlier [[diagnose]] too")
    spec = d.get("spec")
    if not isinstance(spec, dict) or not spec:
        raise StudyError(f"{where}.spec: a non-empty table of the spec keys the rerun changes")
    flat = {k: _scalar(f"{where}.spec.{k}", v) for k, v in _flatten(spec).items()}
    for k in flat:
        if not k.startswith("numerics."):
            raise StudyError(f"{where}.spec.{k}: a diagnosis reruns the same point and seed "
                             "with other numerics: numerics.* keys only")
    kinds = d.get("kinds", sorted(SIMULATION_FAILURES))
    if (not isinstance(kinds, list) or not kinds or
            not all(isinstance(k, str) and k in SIMULATION_FAILURES for k in kinds)):
        raise StudyError(f"{where}.kinds: failure kinds among "
                         f"{', '.join(sorted(SIMULATION_FAILURES))}, got {kinds!r}")
    title = d.get("title", "")
    if not isinstance(title, str):
        raise StudyError(f"{where}.title: a string, got {title!r}")
    if all(k in study.spec and _same(study.spec[k], v) for k, v in flat.items()):
        # Runs are deterministic: the rerun would fail again, bit for bit.
        raise StudyError(f"{where}.spec: the study's [spec] already sets "
                         f"{', '.join(f'{k} = {v!r}' for k, v in flat.items())}; a rerun with "
                         "the run's own numerics would fail again bit for bit")
    return Diagnosis(name=name, spec=flat, kinds=list(kinds), title=title)


def _load_share(study: Study, i: int, sh: Any) -> Share:
    """[[share]]: file = another study file (relative to this one), this = one of this study's
    points, that = the same run's point in the other study, seeds (optional) = the seeds of this
    study at which the two are one run (default: all). Both studies must submit the same
    base, [spec] and preset, so that a job of one is a run of the other; the keys each point
    leaves to the base are checked against the jobs' resolved specs when the jobs are matched."""
    where = f"share[{i}]"
    if not isinstance(sh, dict):
        raise StudyError(f"{where}: a table of file, this, that")
    _unknown(sh, SHARE_KEYS, f"{where}.")
    for k in ("file", "this", "that"):
        if k not in sh:
            raise StudyError(f"{where}.{k}: missing (file = the other study, this = one of this "
                             "study's points, that = the same run's point there)")
    if not isinstance(sh["file"], str):
        raise StudyError(f"{where}.file: the path of a study file, got {sh['file']!r}")
    other_path = (study.path.parent / sh["file"]).resolve()
    if other_path == study.path.resolve():
        raise StudyError(f"{where}.file: the study itself")
    try:
        other = load(other_path, _shares=False)
    except StudyError as e:
        raise StudyError(f"{where}.file: {e}") from None
    for k in ("this", "that"):
        if not isinstance(sh[k], dict) or not sh[k]:
            raise StudyError(f"{where}.{k}: a table of KEY = value, got {sh[k]!r}")
    this = {k: _scalar(f"{where}.this.{k}", v) for k, v in _flatten(sh["this"]).items()}
    that = {k: _scalar(f"{where}.that.{k}", v) for k, v in _flatten(sh["that"]).items()}
    if not any(_same_point(this, pt) for pt in study.points()):
        raise StudyError(f"{where}.this: {this} is not one of this study's points")
    if not any(_same_point(that, pt) for pt in other.points()):
        raise StudyError(f"{where}.that: {that} is not one of {other.name}'s points")
    for k in set(this) & set(that):
        if not _same(this[k], that[k]):
            raise StudyError(f"{where}: {k} is {this[k]} here and {that[k]} there: not one run")
    if other.base_text != study.base_text:
        raise StudyError(f"{where}.file: {other.name} runs another base spec "
                         f"({other.base}); a job of it is not a run of this study")
    if other.preset != study.preset or not _same_point(other.spec, study.spec):
        diff = sorted(k for k in set(other.spec) | set(study.spec)
                      if k not in other.spec or k not in study.spec
                      or not _same(other.spec[k], study.spec[k]))
        raise StudyError(f"{where}.file: {other.name} sets other [spec] keys or preset "
                         f"({', '.join(diff) or 'preset'}); a job of it is not a run of this study")
    seeds = sh.get("seeds")
    if seeds is not None:
        if (not isinstance(seeds, list) or not seeds
                or not all(isinstance(x, int) and not isinstance(x, bool) for x in seeds)
                or len(set(seeds)) != len(seeds)):
            raise StudyError(f"{where}.seeds: a list of distinct seeds of study.seeds, got "
                             f"{seeds!r}")
        mine = [x for x in seeds if x not in study.seeds]
        if mine:
            raise StudyError(f"{where}.seeds: {mine} not in study.seeds {study.seeds}")
        theirs = [x for x in seeds if x not in other.seeds]
        if theirs:
            raise StudyError(f"{where}.seeds: {other.name} does not run seeds {theirs} "
                             f"(its seeds: {other.seeds})")
    new = Share(other=other, this=this, that=that, index=i,
                seeds=None if seeds is None else list(seeds))
    if any(sh2.overlaps(new) for sh2 in study.shares):
        raise StudyError(f"{where}.this: {this} is shared twice"
                         + (f" at one of seeds {seeds}" if seeds is not None else ""))
    return new


# ---- matching jobs to runs -------------------------------------------------------------------

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
                    "numerics.contact_within_prisms": False,
                    "numerics.contact_prisms_overlap_only": False,
                    "numerics.remesh_on_surface": False,
                    "numerics.remesh_rescue": False,
                    "numerics.remesh_rebuild": False,
                    "numerics.remesh_keep_out_um": 0.0,
                    "scene.polarity_from_preparation": False}


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
    value = _spec_value(spec, key)
    if value is None and key in KEYS_ADDED_LATER and spec:
        return KEYS_ADDED_LATER[key]
    return value


# Keys added later whose default is not the value of the jobs before them: a study that leaves
# one unset runs at today's default, and a stored job at the earlier value is not its run (a
# study that ran before the change says `key = <earlier value>` in its [spec]).
DEFAULTS_CHANGED = {"numerics.remesh_on_surface": True}


def _base_keys(study: Study) -> set:
    """The dotted keys the study's base spec sets (TOML or JSON; none if it is neither)."""
    if not study.base_text:
        return set()
    try:
        doc = tomllib.loads(study.base_text)
    except tomllib.TOMLDecodeError:
        try:
            doc = json.loads(study.base_text)
        except ValueError:
            return set()
    return set(_flatten(doc)) if isinstance(doc, dict) else set()


def _matches(study: Study, run: Run, spec: Dict[str, Any],
             settings: Optional[Dict[str, Any]] = None) -> bool:
    """Whether a job's resolved spec is this run's (or, with `settings`, the run with those
    keys: a diagnosis rerun)."""
    if settings is None:
        settings = study.settings(run)
    for k, v in settings.items():
        got = _resolved_value(spec, k)
        if got is None:
            if k in run.point or k == "seed":
                return False
            continue  # a key the resolved spec does not echo (e.g. an alias): cannot check
        if not _same(got, v):
            return False
    for k, now in DEFAULTS_CHANGED.items():
        if k in settings or k in _base_keys(study):
            continue  # set by the study (checked above) or by its base spec (then both agree)
        if not _same(_resolved_value(spec, k), now):
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
    own, _ = _jobs_by_run(study, client._list(tag=study.tag))
    own_specs = [(study.runs()[i], json.loads(j.spec_json) if j.spec_json else {})
                 for i, js in own.items() for j in js]
    if not _share_base_verified(study, sh, own_specs):
        return None
    other_runs = sh.other.runs()
    k = next((k for k, r in enumerate(other_runs)
              if r.seed == run.seed and _same_point(r.point, sh.that)), None)
    if k is None:
        return None
    other_jobs, _ = _jobs_by_run(sh.other, client._list(tag=sh.other.tag))
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
    from activefoam.client import _state_name
    runs = study.runs()
    out: Dict[int, List[Any]] = {}
    if not study.shares:
        return out
    own_specs = [(runs[i], json.loads(j.spec_json) if j.spec_json else {})
                 for i, js in own.items() for j in js]
    listed: Dict[str, List[Any]] = {}
    for sh in study.shares:
        if sh.other.tag not in listed:
            listed[sh.other.tag] = client._list(tag=sh.other.tag)
        other_jobs, _ = _jobs_by_run(sh.other, listed[sh.other.tag])
        other_runs = sh.other.runs()
        for i, run in enumerate(runs):
            mine = own.get(i, [])
            if not sh.covers(run.point, run.seed) or any(_state_name(j.state) != "cancelled"
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
    own, stale = _jobs_by_run(study, client._list(tag=study.tag))
    shared = _shared_jobs(study, client, own)
    found = dict(own)
    source: Dict[int, str] = {}
    for i, js in shared.items():
        found[i] = js
        source[i] = _share_of(study, study.runs()[i]).other.name
    return found, source, stale


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
    from activefoam.client import _state_name
    if not jobs:
        return True
    last = jobs[-1]
    state = _state_name(last.state)
    if state == "cancelled":
        return True
    if state == "failed":
        return (_retries(retry_failed, last.failure_kind) or
                last.failure_kind not in SIMULATION_FAILURES)
    return False


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
    for j in sorted(client._list(tag=study.diag_tag), key=lambda j: (j.created_utc, j.id)):
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


def _diag_needed(jobs: List[Any]) -> bool:
    """A diagnosis is run once: a rerun queued, running, ended or cancelled (by hand: a
    decision) stands; one that failed outside the simulation (an engine error, a lost worker) is
    submitted again."""
    from activefoam.client import _state_name
    if not jobs:
        return True
    last = jobs[-1]
    return _state_name(last.state) == "failed" and last.failure_kind not in SIMULATION_FAILURES


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


def submit_diagnoses(study: Study, client: Any, out=sys.stderr) -> int:
    """Submits the diagnosis reruns of the study's own runs that failed in the simulation with a
    kind a [[diagnose]] table names and have no rerun yet; returns how many."""
    from activefoam.client import _setting, _state_name
    from activefoam.v1 import service_pb2
    if not study.diagnoses:
        return 0
    found, source, _ = _run_jobs(study, client)
    diag = _diag_jobs(study, client)
    runs = study.runs()
    n = 0
    for i, run in enumerate(runs):
        have = found.get(i, [])
        if i in source or not have:
            continue  # a shared run is diagnosed by the study that owns it
        last = have[-1]
        if _state_name(last.state) != "failed" or last.failure_kind not in SIMULATION_FAILURES:
            continue
        for d in study.diagnoses:
            if last.failure_kind not in d.kinds:
                continue
            jobs = diag.get(i, {}).get(d.name, [])
            if not _diag_needed(jobs):
                continue
            if _diag_is_noop(d, last):
                print(f"study {study.name}: {run.label()} failed ({last.failure_kind}): "
                      f"diagnosis {d.name!r} {NOOP_TEXT} ({', '.join(d.spec)}): the study "
                      "file's [[diagnose]] needs other values", file=out)
                continue
            settings = [_setting(k, v) for k, v in study.diag_settings(run, d).items()]
            settings.sort(key=lambda x: not x.startswith("scene="))
            req = service_pb2.SubmitJobRequest(
                spec_text=study.base_text, settings=settings, tag=study.diag_tag,
                priority=study.priority - 1,  # after the study's own runs
                idempotency_key=f"{study.diag_tag}:{d.name}:{study.run_id(run)}:{len(jobs)}")
            try:
                resp = client._call("SubmitJob", req, f"diagnose {run.label()} ({d.name})")
            except ValueError as e:
                raise StudyError(f"{study.path}: diagnose {d.name!r} of {run.label()}: {e}"
                                 ) from None
            if resp.created:
                n += 1
                print(f"study {study.name}: {run.label()} failed ({last.failure_kind}): "
                      f"diagnosis {d.name!r} submitted", file=out)
    return n


def _diag_outcome(job: Any, failed_at_s: float) -> Tuple[str, bool]:
    """A diagnosis rerun's outcome in words, and whether it ran past the failure."""
    from activefoam.client import _state_name
    state = _state_name(job.state)
    t = float(getattr(job, "t_s", 0.0) or 0.0)
    if state == "succeeded":
        return "ran to the end", True
    if state == "failed" and job.failure_kind in SIMULATION_FAILURES:
        when = "later" if t > failed_at_s + 1e-9 else "too"
        return f"failed {when}: {job.failure_kind} at {t:.0f} s", False
    if state == "failed":
        return f"did not run ({job.failure_kind})", False
    if state in ("queued", "running"):
        return f"{state} ({100 * float(job.progress):.0f} %)", False
    return state, False


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
    carrying the run's settings and base spec's hash (collected since 2026-11-26) is taken only
    if they are this run's today: a study whose [spec] or base file changed does not take the
    old runs."""
    import pandas as pd
    d = Path(data_dir)
    for f in ("runs.csv", "samples.csv.gz", "msrd.csv.gz"):
        if not (d / f).is_file():
            raise StudyError(f"--with-data: {d / f} is missing (a report's data folder holds "
                             "runs.csv, samples.csv.gz and msrd.csv.gz)")
    meta = d / "collected.json"
    if meta.is_file():
        name = json.loads(meta.read_text()).get("study")
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
    from activefoam.client import _state_name
    return (carried is not None and i in carried.rows and
            (not have or _state_name(have[-1].state) == "cancelled"))


# ---- run -----------------------------------------------------------------------------------------

def live_stale_jobs(study: Study, client: Any) -> List[Any]:
    """The study's queued or running jobs that are no run of the file as it is now (an earlier
    version's: a changed [spec], grid or seed list). They would go on and take the machine."""
    from activefoam.client import _state_name
    _, stale = _jobs_by_run(study, client._list(tag=study.tag))
    return [j for j in stale if _state_name(j.state) in ("queued", "running")]


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
    spec foamd refuses stops the
    submission and cancels what this call submitted (a study is submitted whole or not at all),
    then raises StudyError."""
    from activefoam.client import _setting, _state_name
    runs = study.runs()
    submitted: List[str] = []
    held = 0
    from activefoam.v1 import service_pb2
    # The runs of their own first: a shared run is matched against the other study's jobs with
    # the base's values that this study's own jobs show.
    order = ([i for i, r in enumerate(runs) if _share_of(study, r) is None] +
             [i for i, r in enumerate(runs) if _share_of(study, r) is not None])
    found: Dict[int, List[Any]] = {}
    for n, i in enumerate(order):
        if n == 0 or (_share_of(study, runs[i]) is not None and
                      _share_of(study, runs[order[n - 1]]) is None):
            found, _, _ = _run_jobs(study, client)
        run = runs[i]
        have = found.get(i, [])
        if not _needs_job(have, retry_failed):
            held += 1
            continue
        if _takes_carried(have, carried, i) and not (
                carried.rows[i]["state"] == "failed" and
                _retries(retry_failed, str(carried.rows[i].get("failure_kind") or ""))):
            held += 1
            continue
        failed = sum(1 for j in have if _state_name(j.state) == "failed")
        if failed >= MAX_ATTEMPTS:
            print(f"study {study.name}: {run.label()}: {failed} attempts failed; not "
                  "submitted again", file=out)
            held += 1
            continue
        # A shared run is submitted as its owner's run (the same base, [spec] and preset, by
        # the share's rules), whichever study is submitted first: then the owner finds it as
        # its own, and the idempotency key is the one the owner would use.
        owner, owner_run, attempts = study, run, len(have)
        owned = _owner_of_shared_run(study, client, run)
        if owned is not None:
            owner, owner_run, attempts = owned
            print(f"study {study.name}: {run.label()} is {owner.name}'s run "
                  f"{owner_run.label()} (shared): submitted as {owner.name}'s", file=out)
        settings = [_setting(k, v) for k, v in owner.settings(owner_run).items()]
        # The scene first, as the client does: its table's defaults apply before the others.
        settings.sort(key=lambda s: not s.startswith("scene="))
        req = service_pb2.SubmitJobRequest(
            spec_text=owner.base_text, settings=settings, tag=owner.tag,
            priority=owner.priority,
            idempotency_key=f"{owner.tag}:{owner.run_id(owner_run)}:{attempts}")
        try:
            resp = client._call("SubmitJob", req, f"submit {run.label()}")
        except ValueError as e:
            for jid in submitted:
                try:
                    client.cancel(jid, f"study {study.name}: submission aborted ({run.label()} "
                                       "was refused)")
                except Exception:  # noqa: BLE001 - best effort; the error below matters
                    pass
            raise StudyError(f"{study.path}: {run.label()}: {e}") from None
        if resp.created:
            submitted.append(resp.job_id)
        else:
            held += 1
    return len(submitted), held


def _progress(study: Study, client: Any, carried: Optional[Carried] = None
              ) -> Tuple[Dict[str, int], float, List[Any]]:
    from activefoam.client import _state_name
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
        s = _state_name(j.state)
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


# ---- data: the store's per-run results, samples and MSRD curves --------------------------------

def collect(study: Study, client: Any, out_dir: os.PathLike,
            carried: Optional[Carried] = None) -> Path:
    """Writes the study's data from the store into out_dir: runs.csv (one row per run: state,
    failure, outcome, seed, the swept keys, the run's settings, every result), samples.csv.gz
    (the sample columns the figures need) and msrd.csv.gz (each run's MSRD curve). A run with
    no live or ended job in the store takes its row, samples and curve from `carried` (an
    earlier store's data), if that holds it. Returns out_dir."""
    import pandas as pd
    from activefoam.client import _state_name
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    found, source, stale = _run_jobs(study, client)
    diag = _diag_of_runs(study, client, source)
    rows, samples, curves = [], [], []
    n_carried = 0
    for i, run in enumerate(study.runs()):
        row: Dict[str, Any] = {"run": i, **run.point, "seed": run.seed,
                               "settings": json.dumps(study.settings(run), sort_keys=True),
                               "base_sha256": _base_sha(study)}
        have = found.get(i, [])
        if _takes_carried(have, carried, i):
            old = carried.rows[i]
            row.update({k: v for k, v in old.items() if k not in row and k != "carried_from"})
            row["carried_from"] = str(carried.source)
            jid = old["job_id"]
            samples += carried.samples[carried.samples["job_id"] == jid].to_dict("records")
            curves += carried.msrd[carried.msrd["job_id"] == jid].values.tolist()
            rows.append(row)
            n_carried += 1
            continue
        if not have:
            row.update(state="missing", attempts=0)
            rows.append(row)
            continue
        j = have[-1]
        if i in source:
            row["shared_from"] = source[i]
        row.update(job_id=j.id, state=_state_name(j.state), failure_kind=j.failure_kind,
                   reason=j.reason, outcome=j.outcome, attempts=len(have), t_end_s=j.t_s)
        # A diagnosis that applies to the run's failure but would rerun the same numerics.
        noop = ([d.name for d in study.diagnoses
                 if j.failure_kind in d.kinds and d.name not in diag.get(i, {})
                 and _diag_is_noop(d, j)]
                if row["state"] == "failed" and i not in source else [])
        if row["state"] == "failed" and (diag.get(i) or noop):
            # Each diagnosis's last rerun: "NAME: outcome (job)"; the failure is the point's
            # unless one ran past it.
            texts, past = [], False
            for name, js in diag.get(i, {}).items():
                text, ran_past = _diag_outcome(js[-1], float(j.t_s or 0.0))
                texts.append(f"{name}: {text} ({js[-1].id})")
                past = past or ran_past
            texts += [f"{name}: {NOOP_TEXT}" for name in noop]
            row.update(diagnoses="; ".join(texts), diag_ran_past=past)
        if row["state"] in ("succeeded", "failed"):
            job = client.job(j.id)
            r = job._results(True)
            row.update({x.name: x.value for x in r.results})
            cols = list(r.columns)
            keep = [c for c in SAMPLE_COLUMNS if c in cols]
            idx = [cols.index(c) for c in keep]
            for s in r.samples:
                samples.append({"job_id": j.id, "t_s": s.t_s,
                                **{c: s.values[k] for c, k in zip(keep, idx)}})
            for c in getattr(r, "curves", []):
                if c.name == "msrd":
                    curves += [[j.id, x, y] for x, y in zip(c.x, c.y)]
        rows.append(row)
    pd.DataFrame(rows).to_csv(out / "runs.csv", index=False)
    # gzip without a timestamp: the same data gives the same bytes (a report regenerated from
    # the store changes nothing in git unless the runs changed).
    gz = {"method": "gzip", "mtime": 0}
    pd.DataFrame(samples, columns=["job_id", "t_s", *SAMPLE_COLUMNS]).to_csv(
        out / "samples.csv.gz", index=False, compression=gz)
    pd.DataFrame(curves, columns=["job_id", "lag_s", "msrd_um2"]).to_csv(
        out / "msrd.csv.gz", index=False, compression=gz)
    meta = {"study": study.name, "file": str(study.path), "tag": study.tag,
            "collected_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "runs": len(rows), "stale_jobs": [j.id for j in stale],
            "shared_runs": {str(i): src for i, src in source.items()},
            "carried_runs": n_carried}
    (out / "collected.json").write_text(json.dumps(meta, indent=1) + "\n")
    return out


@dataclass
class Data:
    runs: Any       # DataFrame, one row per run, with the derived metrics of METRICS
    samples: Any    # DataFrame job_id, t_s, sample columns
    msrd: Any       # DataFrame job_id, lag_s, msrd_um2


def load_data(study: Study, data_dir: os.PathLike) -> Data:
    import pandas as pd
    d = Path(data_dir)
    for f in ("runs.csv", "samples.csv.gz", "msrd.csv.gz"):
        if not (d / f).is_file():
            raise StudyError(f"data: {d / f} is missing (collect it with `report` against foamd)")
    runs = pd.read_csv(d / "runs.csv")
    samples = pd.read_csv(d / "samples.csv.gz")
    msrd = pd.read_csv(d / "msrd.csv.gz")
    runs = derive_metrics(study, runs, samples, msrd)
    return Data(runs, samples, msrd)


def derive_metrics(study: Study, runs: Any, samples: Any, msrd: Any) -> Any:
    """Adds the per-run metrics of METRICS (NaN where a run has none: not finished, a fit that
    did not converge). θ, shape index and unique contacts at the end are the last finite sample;
    θ and the shape index over the last hour are the means of the finite samples in the run's
    last hour (its last half when it is shorter than 2 h): the plateau the last sample wanders
    about (θ by ±3° over minutes as cells rearrange, the shape index by 0.05–0.10 in an hour).
    MSRD at the end is the curve's longest lag, over r²."""
    import numpy as np
    runs = runs.copy()
    last = {}
    if len(samples):
        for jid, g in samples.groupby("job_id"):
            g = g.sort_values("t_s")
            vals = {}
            for col, name in (("theta_deg", "theta_end_deg"),
                              ("shape_index_mean", "shape_index_end"),
                              ("unique_contacts_norm", "unique_contacts_end")):
                if col in g:
                    v = g[col].to_numpy(dtype=float)
                    v = v[np.isfinite(v)]
                    vals[name] = v[-1] if len(v) else math.nan
            for col, name in (("theta_deg", "theta_last_hour_deg"),
                              ("shape_index_mean", "shape_index_last_hour")):
                if col in g and len(g):
                    t = g["t_s"].to_numpy(dtype=float)
                    v = g[col].to_numpy(dtype=float)
                    late = v[(t >= t[-1] - min(3600.0, t[-1] / 2)) & np.isfinite(v)]
                    vals[name] = late.mean() if len(late) else math.nan
            # The largest cell volume error over the run's samples (the result of the same
            # name is the value at the run's end only).
            if "volume_error_max" in g:
                v = g["volume_error_max"].to_numpy(dtype=float)
                v = v[np.isfinite(v)]
                vals["volume_error_peak"] = v.max() if len(v) else math.nan
            last[jid] = vals
    mend = {}
    if len(msrd):
        for jid, g in msrd.groupby("job_id"):
            g = g.sort_values("lag_s")
            v = g["msrd_um2"].to_numpy(dtype=float)
            v = v[np.isfinite(v)]
            mend[jid] = v[-1] if len(v) else math.nan
    ok = runs["state"] == "succeeded"
    for name in ("theta_end_deg", "theta_last_hour_deg", "shape_index_end",
                 "shape_index_last_hour", "unique_contacts_end"):
        runs[name] = [last.get(j, {}).get(name, math.nan) if s == "succeeded" else math.nan
                      for j, s in zip(runs.get("job_id", [None] * len(runs)), runs["state"])]
    runs["volume_error_peak"] = [last.get(j, {}).get("volume_error_peak", math.nan)
                                 for j in runs.get("job_id", [None] * len(runs))]
    r = study_radius(study)
    runs["msrd_end_over_r2"] = [mend.get(j, math.nan) / r**2 if s == "succeeded" else math.nan
                                for j, s in zip(runs.get("job_id", [None] * len(runs)),
                                                runs["state"])]
    fit_ok = runs["eq1_ok"] == 1 if "eq1_ok" in runs else np.zeros(len(runs), bool)
    # A fit whose τ_f is longer than the run saw less than 1 − 1/e of the relaxation: its θ_eq is
    # an extrapolation past the data (fig8's p_a r/2γ = 0.33, α = 0.75 seed 2: θ rising 36° →
    # 83° over 6 h, fitted θ_eq = 138°, τ_f = 12 h). The engine accepts τ_f up to 10× the span
    # (a fit, not a measurement); a study's trend does not count it.
    runs["eq1_beyond_run"] = _eq1_beyond_run(runs, fit_ok & ok)
    fit_ok = fit_ok & ~runs["eq1_beyond_run"]
    for name in ("theta_eq_deg", "tau_f_s"):  # the fit as the engine gave it, for the record
        runs[name + "_fit"] = runs[name] if name in runs else math.nan
    for name in ("theta_eq_deg", "tau_f_s"):
        src = runs[name] if name in runs else np.full(len(runs), math.nan)
        runs[name] = np.where(fit_ok & ok, src, math.nan)
    tau_p = runs["cells.tau_p_s"] if "cells.tau_p_s" in runs else float(
        study.spec.get("cells.tau_p_s", 600.0))
    runs["tau_f_over_tau_p"] = runs["tau_f_s"] / tau_p
    for name in ("mixing_time_s", "mixing_time_less_rotation_s"):
        if name not in runs:
            runs[name] = math.nan
        runs[name] = np.where(ok, runs[name], math.nan)
    return runs


def _eq1_beyond_run(runs: Any, fitted: Any) -> Any:
    """Per run: Eq. 1 converged but its τ_f exceeds the run's simulated length (t_end_s)."""
    import numpy as np
    if "tau_f_s" not in runs or "t_end_s" not in runs:
        return np.zeros(len(runs), bool)
    tau = runs["tau_f_s"].to_numpy(dtype=float)
    t_end = runs["t_end_s"].to_numpy(dtype=float)
    with np.errstate(invalid="ignore"):
        return np.asarray(fitted, bool) & np.isfinite(tau) & np.isfinite(t_end) & (tau > t_end)


def study_radius(study: Study) -> float:
    return float(study.spec.get("cells.radius_mean_um", 8.88))


# ---- report: tables and figures --------------------------------------------------------------

def summary_table(study: Study, runs: Any, metrics: Sequence[str] = tuple(METRICS)) -> Any:
    """Per grid point: runs, succeeded, failed (with their failure kinds), and per metric n,
    median, q25, q75 over seeds (an optional metric only where some run has it)."""
    import pandas as pd
    metrics = shown_metrics(runs, metrics)
    keys = study.swept_keys()
    out = []
    for point in study.points():
        sel = _runs_of_point(runs, point, keys)
        row: Dict[str, Any] = {k: point.get(k) for k in keys}
        row["runs"] = len(sel)
        row["succeeded"] = int((sel["state"] == "succeeded").sum())
        failed = sel[sel["state"] == "failed"]
        row["failed"] = len(failed)
        row["failures"] = ",".join(sorted(set(failed.get("failure_kind", pd.Series(dtype=str))
                                              .dropna().astype(str))))
        # Failures a diagnosis rerun ran past: those numerics', not the point's.
        row["failed_ran_past"] = int(_ran_past(failed).sum())
        row["missing"] = int(sel["state"].isin(["missing", "queued", "running",
                                                "cancelled"]).sum())
        # The runs' numerical health: steps the engine redid at a shorter step (an inverted
        # triangle, a penetration, an oscillation: docs/science/motion-convergence.md) and the
        # largest cell volume error, so that a point's numbers can be read against them.
        redone = trends.finite(sel["steps_rejected"]) if "steps_rejected" in sel else []
        row["steps_redone"] = int(sum(redone)) if len(redone) else math.nan
        vol = trends.finite(sel["volume_error_peak"]) if "volume_error_peak" in sel else []
        row["volume_error_peak"] = float(max(vol)) if len(vol) else math.nan
        for m in metrics:
            v = trends.finite(sel[m]) if m in sel else []
            row[f"{m}_n"] = len(v)
            row[f"{m}_median"] = trends.median(v)
            row[f"{m}_q25"] = float(pd.Series(v).quantile(0.25)) if len(v) else math.nan
            row[f"{m}_q75"] = float(pd.Series(v).quantile(0.75)) if len(v) else math.nan
        out.append(row)
    return pd.DataFrame(out, columns=list(out[0].keys()) if out else keys)


def _ran_past(runs: Any) -> Any:
    """Per run: whether a diagnosis rerun of it ran past its failure (False without the column:
    data collected before diagnoses)."""
    import pandas as pd
    if "diag_ran_past" not in runs:
        return pd.Series(False, index=runs.index)
    return runs["diag_ran_past"].map(lambda v: v is True or str(v).lower() == "true")


def _toml(v: Any) -> str:
    return ("true" if v else "false") if isinstance(v, bool) else str(v)


def failed_runs_markdown(study: Study, runs: Any) -> str:
    """The failed runs, each with its failure and its diagnoses' outcomes; empty if none."""
    if "state" not in runs:
        return ""
    failed = runs[runs["state"] == "failed"]
    if not len(failed):
        return ""
    keys = study.swept_keys()
    if study.diagnoses:
        how = ("a diagnosis reruns the run with some keys changed (the study file's [[diagnose]] "
               "tables: " + "; ".join(f"{d.name} sets " + ", ".join(
                   f"{k} = {_toml(v)}" for k, v in d.spec.items())
                   + (f" ({d.title})" if d.title else "") + " for " + ", ".join(d.kinds)
                   for d in study.diagnoses)
               + "). A rerun that ran to the end says the failure was those numerics', not the "
               "point's: the verdict table's `failed` leaves it out.")
    else:
        how = "the study file has no [[diagnose]] tables: each failure counts as its point's."
    lines = ["## Failed runs", "",
             "A failure the simulation reached (its kind, the time, the job); " + how, ""]
    for _, r in failed.iterrows():
        # The point's own keys (a key of another grid is unset here).
        point = ", ".join(f"{k} = {_cell(r.get(k))}" for k in keys if _cell(r.get(k)) != "—")
        t = r.get("t_end_s")
        when = f" at {float(t):.0f} s" if t == t and t is not None else ""
        diag = r.get("diagnoses")
        diag = diag if isinstance(diag, str) and diag else "no diagnosis"
        lines.append(f"- {point}, seed {r['seed']}: {_cell(r.get('failure_kind'))}{when} "
                     f"({_cell(r.get('job_id'))}); {diag}")
    return "\n".join(lines) + "\n"


def unsaturated_fits_markdown(study: Study, runs: Any) -> str:
    """The runs whose Eq. 1 fit converged with τ_f longer than the run (not counted); empty if
    none."""
    if "eq1_beyond_run" not in runs or not runs["eq1_beyond_run"].any():
        return ""
    keys = study.swept_keys()
    lines = ["## Eq. 1 fits longer than their run", "",
             "Converged, but τ_f exceeds the run's length: the run saw less than 1 − 1/e of the "
             "relaxation, and θ_eq extrapolates past the data. Their θ_eq and τ_f are not "
             "counted (the table's n); θ at the end and over the last hour are.", ""]
    for _, r in runs[runs["eq1_beyond_run"]].iterrows():
        point = ", ".join(f"{k} = {_cell(r.get(k))}" for k in keys if _cell(r.get(k)) != "—")
        lines.append(f"- {point}, seed {r['seed']}: τ_f = {float(r['tau_f_s_fit']):.0f} s against "
                     f"a {float(r['t_end_s']):.0f} s run, θ_eq = {float(r['theta_eq_deg_fit']):.1f}° "
                     f"({_cell(r.get('job_id'))})")
    return "\n".join(lines) + "\n"


def _cell(v: Any) -> str:
    """A key's value in a table; a point of another grid leaves it unset."""
    return "—" if v is None or (isinstance(v, float) and v != v) else str(v)


def summary_markdown(study: Study, table: Any) -> str:
    """The summary as a readable table: per point, runs (succeeded / failed, with the failure
    kinds) and each metric as median [q25, q75] over its n runs."""
    keys = study.swept_keys()
    shown = [m for m in METRICS if f"{m}_median" in table]
    head = (keys + ["runs", "ok", "failed"] + [METRICS[m] for m in shown] +
            ["steps redone", "largest volume error"])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for _, r in table.iterrows():
        cells = [_cell(r.get(k)) for k in keys]
        past = int(r.get("failed_ran_past", 0) or 0)
        cells += [str(r["runs"]), str(r["succeeded"]),
                  f"{r['failed']}" + (f" ({r['failures']}" + (f"; {past} ran past on a "
                                                               "diagnosis rerun" if past else "")
                                      + ")" if r["failed"] else "")]
        for m in shown:
            med = r[f"{m}_median"]
            cells.append("—" if math.isnan(med) else
                         f"{med:.3g} [{r[f'{m}_q25']:.3g}, {r[f'{m}_q75']:.3g}] ({r[f'{m}_n']})")
        redone, vol = r.get("steps_redone", math.nan), r.get("volume_error_peak", math.nan)
        cells.append("—" if redone != redone else str(int(redone)))
        cells.append("—" if vol != vol else f"{100 * vol:.2g} %")
        lines.append("| " + " | ".join(cells) + " |")
    head_line = f"# {study.title}\n\n" + (f"Scale: {study.scale}.\n\n" if study.scale else "")
    return (head_line + "Median [q25, q75] (n runs) over seeds; mixing time is capped at the "
            "run's length where MSRD never reached r²; θ_eq and τ_f count where Eq. 1 converged "
            "with τ_f no longer than the run (a longer one extrapolates θ_eq past the data). "
            "Steps redone: over the point's runs, the "
            "steps the engine rejected and redid at a shorter step (inverted triangles, "
            "penetration, oscillation); largest volume error: the largest |V − V₀|/V₀ of any "
            "cell at any sample of them (a run fails beyond numerics.max_volume_error; — where "
            "the data has no such column). Failures are "
            "numerical, as the supplement's hatched runs that \"failed to converge\".\n\n" +
            "\n".join(lines) + "\n")


def _markdown(df: Any, floatfmt: str = ".3g") -> str:
    cols = list(df.columns)
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for _, r in df.iterrows():
        cells = []
        for c in cols:
            v = r[c]
            if isinstance(v, float):
                cells.append("—" if math.isnan(v) else format(v, floatfmt))
            else:
                cells.append(str(v))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _value(v: Any) -> str:
    """A key's value in a figure's labels: 0.037162162162162164 crowds a panel's title."""
    return format(v, ".4g") if isinstance(v, float) else str(v)


def _label(study: Study, key: str) -> str:
    if key == study.x and study.x_label:
        return study.x_label
    if key == study.by and study.by_label:
        return study.by_label
    return key


def _series(study: Study, data: Data, sel: Any, col: str) -> Tuple[Any, Any, Any, Any]:
    """Median and IQR of a sample column over the selected runs, on the common sample times."""
    import numpy as np
    ids = [j for j, s in zip(sel.get("job_id", []), sel["state"]) if s == "succeeded"]
    g = data.samples[data.samples["job_id"].isin(ids)]
    if not len(g) or col not in g:
        return (np.array([]),) * 4
    piv = g.pivot_table(index="t_s", columns="job_id", values=col)
    t = piv.index.to_numpy(dtype=float)
    a = piv.to_numpy(dtype=float)
    with np.errstate(all="ignore"):
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            med = np.nanmedian(a, axis=1)
            q25 = np.nanpercentile(a, 25, axis=1)
            q75 = np.nanpercentile(a, 75, axis=1)
    return t, med, q25, q75


def _msrd_series(data: Data, sel: Any) -> Tuple[Any, Any]:
    import numpy as np
    ids = [j for j, s in zip(sel.get("job_id", []), sel["state"]) if s == "succeeded"]
    g = data.msrd[data.msrd["job_id"].isin(ids)]
    if not len(g):
        return np.array([]), np.array([])
    piv = g.pivot_table(index="lag_s", columns="job_id", values="msrd_um2")
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return piv.index.to_numpy(dtype=float), np.nanmedian(piv.to_numpy(dtype=float), axis=1)


def render(study: Study, data: Data, out_dir: os.PathLike) -> List[Path]:
    """The study's figure(s) and tables from its data: NAME-curves.png (θ(t) with the Eq. 1 fit
    of the median parameters, and MSRD(t) on log–log axes with the r² line, per value of `by`),
    NAME-trends.png (θ_eq, τ_f/τ_p, shape index, MSRD at the end, unique contacts, mixing time
    against x, one line per `by`, median and IQR over seeds, failed runs marked), summary.csv,
    summary.md, and for a fitness study fitness.csv / fitness.md."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: List[Path] = []
    runs = data.runs
    table = summary_table(study, runs)
    table.to_csv(out / "summary.csv", index=False)
    extra = [m for m in (failed_runs_markdown(study, runs),
                         unsaturated_fits_markdown(study, runs)) if m]
    (out / "summary.md").write_text(summary_markdown(study, table)
                                    + "".join("\n" + m for m in extra))
    written += [out / "summary.csv", out / "summary.md"]

    x = study.x or study.swept_keys()[0]
    by = study.by
    by_values = list(dict.fromkeys(v for p in study.points() for k, v in p.items() if k == by)) \
        if by else [None]
    x_values = list(dict.fromkeys(p[x] for p in study.points() if x in p))
    r = study_radius(study)
    colors = plt.cm.viridis(np.linspace(0, 0.9, max(len(x_values), 1)))

    # θ(t) and MSRD(t), one row per value of `by`.
    fig, axes = plt.subplots(len(by_values), 2, figsize=(10, 3.2 * len(by_values)),
                             squeeze=False)
    for row, bv in enumerate(by_values):
        ax_t, ax_m = axes[row]
        for c, xv in zip(colors, x_values):
            sel = runs[[_same(v, xv) for v in runs[x]]]
            if by:
                sel = sel[[_same(v, bv) for v in sel[by]]]
            t, med, q25, q75 = _series(study, data, sel, "theta_deg")
            if len(t):
                h = t / 3600
                ax_t.plot(h, med, color=c, label=f"{_label(study, x)} = {_value(xv)}")
                ax_t.fill_between(h, q25, q75, color=c, alpha=0.2, lw=0)
                ok = sel[np.isfinite(sel["theta_eq_deg"])] if "theta_eq_deg" in sel else sel[:0]
                if len(ok) and "theta0_deg" in ok:  # Eq. 1's θ0 (Eq. 2's is eq2_…)
                    te = np.median(ok["theta_eq_deg"])
                    t0 = np.median(ok["theta0_deg"])
                    tf = np.median(ok["tau_f_s"])
                    ax_t.plot(h, te + (t0 - te) * np.exp(-t / tf), color=c, ls="--", lw=1)
            lag, m = _msrd_series(data, sel)
            keep = (lag > 0) & np.isfinite(m) & (m > 0)
            if keep.any():
                ax_m.loglog(lag[keep] / 3600, m[keep] / r**2, color=c)
        ax_m.axhline(1.0, color="k", ls=":", lw=1, label="r²")
        title = f"{_label(study, by)} = {_value(bv)}" if by else ""
        ax_t.set(xlabel="t (h)", ylabel="θ (°)", title=title)
        ax_m.set(xlabel="lag (h)", ylabel="MSRD / r²", title=title)
        if row == 0:
            ax_t.legend(fontsize=7)
            ax_m.legend(fontsize=7)
    # Wrapped: a long study title ran off the figure's edge.
    fig.suptitle(textwrap.fill(f"{study.title}: θ(t) (median, IQR; dashed: Eq. 1 with the median "
                               "fit) and MSRD", 120), fontsize=9)
    fig.tight_layout()
    fig.savefig(out / f"{study.name}-curves.png", dpi=110)
    plt.close(fig)
    written.append(out / f"{study.name}-curves.png")

    # Panels against x, one line per `by`.
    panels = ["theta_eq_deg", "tau_f_over_tau_p", "shape_index_end", "msrd_end_over_r2",
              "unique_contacts_end", "mixing_time_s"]
    fig, axes = plt.subplots(2, 3, figsize=(12, 6.5))
    markers = "osD^v<>"
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in x_values)
    where = {str(v): i for i, v in enumerate(x_values)}  # a categorical x: evenly spaced
    for ax, m in zip(axes.flat, panels):
        for k, bv in enumerate(by_values):
            rows = table if not by else table[[_same(v, bv) for v in table[by]]]
            xs = np.array([float(v) if numeric else where[str(v)] for v in rows[x]])
            med = rows[f"{m}_median"].to_numpy(dtype=float)
            lo = med - rows[f"{m}_q25"].to_numpy(dtype=float)
            hi = rows[f"{m}_q75"].to_numpy(dtype=float) - med
            lab = f"{_label(study, by)} = {_value(bv)}" if by else None
            ax.errorbar(xs, med, yerr=[lo, hi], marker=markers[k % len(markers)], capsize=3,
                        label=lab)
            past = rows["failed_ran_past"] if "failed_ran_past" in rows else [0] * len(rows)
            for xv, f, n, p in zip(xs, rows["failed"], rows["runs"], past):
                if f:
                    # A failure a diagnosis rerun ran past is the numerics', not the point's.
                    text = f"{f}/{n} failed" + (f" ({p} ran past on a rerun)" if p else "")
                    ax.annotate(text, (xv, 0), xycoords=("data", "axes fraction"),
                                fontsize=6, color="red", ha="center", va="bottom")
        if study.x_log and numeric:
            ax.set_xscale("log")
        if not numeric:
            ax.set_xticks(range(len(x_values)), [str(v) for v in x_values])
            ax.set_xlim(-0.5, len(x_values) - 0.5)
        ax.set(xlabel=_label(study, x), ylabel=METRICS[m])
    if by:
        axes.flat[0].legend(fontsize=7)
    fig.suptitle(f"{study.title}: median and IQR over seeds", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / f"{study.name}-trends.png", dpi=110)
    plt.close(fig)
    written.append(out / f"{study.name}-trends.png")

    if study.fitness:
        written += render_fitness(study, data, out)
    return written


def _runs_of_point(runs: Any, point: Dict[str, Any], keys: List[str]) -> Any:
    """The rows of `runs` at exactly this grid point: every key it sets has its value, every
    other swept key is unset (a point of another grid)."""
    import pandas as pd
    mask = [True] * len(runs)
    for k in keys:
        col = runs[k] if k in runs else pd.Series([None] * len(runs), index=runs.index)
        if k in point:
            mask = [m and _same(x, point[k]) for m, x in zip(mask, col)]
        else:
            mask = [m and (x is None or (isinstance(x, float) and x != x)) for m, x in
                    zip(mask, col)]
    return runs[mask]


def _point_label(point: Dict[str, Any], key: str) -> str:
    return ", ".join(f"{k} = {v}" for k, v in [(key, point[key])] +
                     [(k, v) for k, v in point.items() if k != key])


def _fitness_pairs(study: Study, runs: Any) -> List[Tuple[Dict[str, Any], Any, Any]]:
    """(candidate point, its reference runs, its own runs) for every candidate grid point."""
    import pandas as pd
    f = study.fitness or {}
    key, ref = f["key"], f["reference"]
    keys = study.swept_keys()
    others = [k for k in keys if k != key]
    points = [p for p in study.points() if key in p]
    refs = [p for p in points if _same(p[key], ref)]
    out = []
    for cand in points:
        if _same(cand[key], ref):
            continue
        matching = [r for r in refs
                    if all(_same(r[k], cand.get(k)) for k in others if k in r)]
        ref_runs = pd.concat([_runs_of_point(runs, r, keys) for r in matching]) if matching \
            else runs.iloc[0:0]
        out.append((cand, ref_runs, _runs_of_point(runs, cand, keys)))
    return out


CALIBRATION_NOTE = """
**The rule's reading.** Two ensembles of equal numerics fail |Δ| < IQR/2 on one metric about
half the time with 5 runs a side (two thirds with 3), so on eight metrics the rule calls equal
numerics fit 0.2 % of the time with 5 seeds (independent metrics; 7 % with 10, 67 % with 30:
docs/science/power.md, "What the fitness rule can certify"). "Not fit" at these ensemble sizes
is therefore no evidence of a difference by itself. The calibrated line is a permutation test of
"the numerics change nothing": the runs are relabelled — each seed's two runs swapped or not
when both settings ran the same seeds (a seed prepares the same spheroids for both), or within
the seeds both ended when those pairs alone can reach p < 0.05 (a run without a partner left
out), else every split of the pooled runs — each metric's difference of means is ranked among its
relabellings, and the smallest rank over the metrics is compared with the same for every
relabelling (min-p: the metrics' correlations kept, no distribution assumed). p < 0.05 says
some metric differs more than relabelling the runs makes it; a larger p says no difference was
found, not that there is none.
"""


def _with_results(runs: Any, metrics: Sequence[str]) -> Any:
    """The runs the calibrated test reads: those with a result for some metric (a metric a run
    lacks is NaN and left out by the rule)."""
    return runs[runs[list(metrics)].notna().any(axis=1)]


def _seeds(runs: Any) -> Optional[List[int]]:
    return [int(x) for x in runs["seed"]] if "seed" in runs else None


def _calibration_runs(ref_ok: Any, cand_ok: Any, n_metrics: int) -> Tuple[Any, Any, bool]:
    """The runs the calibrated test relabels, and whether it relabels within seed pairs.

    Both sides on the same seeds: all of them, paired. Otherwise, where the seeds the two sides
    share form enough pairs for the paired test to reach p < 0.05 at all (its least p is about
    2m/2ⁿ with m metrics: n ≥ 9 for eight), those pairs only: a seed's two runs start from the
    same prepared spheroids, and a run whose seed has no partner (a reference that failed, a
    candidate seed the reference lacks) is left out rather than the pairing given up
    (docs/science/presets.md, session 35). Fewer shared seeds: every split of all the runs."""
    rs, cs = _seeds(ref_ok), _seeds(cand_ok)
    if rs is None or cs is None:
        return ref_ok, cand_ok, False
    if trends.is_paired(rs, cs):
        return ref_ok, cand_ok, True
    if len(set(rs)) != len(rs) or len(set(cs)) != len(cs):
        return ref_ok, cand_ok, False
    common = sorted(set(rs) & set(cs))
    if 2 * max(1, n_metrics) / 2 ** len(common) >= 0.05:
        return ref_ok, cand_ok, False
    keep = lambda r: r[r["seed"].astype(int).isin(common)]  # noqa: E731
    return keep(ref_ok), keep(cand_ok), True


def fitness_calibration(study: Study, runs: Any) -> Any:
    """Per candidate: the permutation test of "the numerics change nothing" over relabellings of
    the candidate's and its reference's runs (within each seed's pair when both ran the same
    seeds), each metric's own p, and the rule's numbers (activefoam.trends.fitness_permutation)."""
    import pandas as pd
    metrics = (study.fitness or {})["metrics"]
    rows = []
    for cand, ref_runs, cand_runs in _fitness_pairs(study, runs):
        ref_ok, cand_ok = _with_results(ref_runs, metrics), _with_results(cand_runs, metrics)
        label = _point_label(cand, study.fitness["key"])
        if len(ref_ok) < trends.MIN_SEEDS or len(cand_ok) < trends.MIN_SEEDS:
            rows.append({"candidate": label, "n_ref": len(ref_ok), "n": len(cand_ok)})
            continue
        n_ref_all, n_all = len(ref_ok), len(cand_ok)
        ref_ok, cand_ok, _ = _calibration_runs(ref_ok, cand_ok, len(metrics))
        null = trends.fitness_permutation(
            ref_ok[metrics].to_numpy(dtype=float), cand_ok[metrics].to_numpy(dtype=float),
            ref_seeds=_seeds(ref_ok), cand_seeds=_seeds(cand_ok))
        row = {"candidate": label, "n_ref": n_ref_all, "n": n_all,
               "n_relabelled_ref": len(ref_ok), "n_relabelled": len(cand_ok),
               "paired": null.paired, "relabellings": null.splits, "exact": null.exact,
               "p_value": null.p_value, "smallest_p": null.smallest_p,
               "most_different": metrics[null.most_metric] if null.most_metric >= 0 else "",
               "worst_ratio": null.worst,
               "worst_metric": metrics[null.worst_metric] if null.worst_metric >= 0 else "",
               "failures": null.failures, "metrics": null.metrics,
               "rule_pass_rate_equal": null.pass_rate}
        row.update({f"p_{m}": v for m, v in zip(metrics, null.p_metric)})
        rows.append(row)
    return pd.DataFrame(rows)


def fitness_table(study: Study, runs: Any) -> Any:
    """Per candidate grid point (fitness.key at another value than the reference) and metric:
    the difference of medians against the reference runs with its bootstrap 95 % interval, the
    seed-to-seed IQR and the verdict (fit: |Δ| < IQR/2). A candidate's reference runs are those
    of the reference points that agree with it on every other key they set: a grid of
    (key × α) is judged α by α, and a candidate from a second grid that also changes another
    setting (e.g. Δt with ε_CG) against the reference of the first."""
    import pandas as pd
    f = study.fitness or {}
    key, ref = f["key"], f["reference"]
    others = [k for k in study.swept_keys() if k != key]
    rows = []
    for cand, ref_runs, cand_runs in _fitness_pairs(study, runs):
        for m in f["metrics"]:
            fit = trends.fitness(ref_runs[m], cand_runs[m])
            row = {k: cand.get(k) for k in others}
            row.update({"candidate": _point_label(cand, key), key: cand[key], "reference": ref,
                        "metric": m, "median_ref": trends.median(ref_runs[m]),
                        "median": trends.median(cand_runs[m]), "diff": fit.diff.diff,
                        "diff_lo95": fit.diff.lo, "diff_hi95": fit.diff.hi,
                        "iqr": fit.iqr, "n_ref": fit.diff.n_a, "n": fit.diff.n_b,
                        "fit": {True: "yes", False: "no", None: "—"}[fit.fit],
                        "why": fit.why})
            rows.append(row)
    return pd.DataFrame(rows)


def fitness_paired(study: Study, runs: Any) -> Any:
    """Per candidate and metric, where the candidate and its reference ran the same seeds: the
    effect seed by seed (activefoam.trends.paired_difference): the median of candidate −
    reference within each seed's pair, its order-statistic interval with its exact coverage,
    how many pairs went up and down, and `found_80`: the shift of this metric alone that the
    calibrated test finds 80 % of the time with these pairs, from the differences' measured SD
    (activefoam.power.paired_detectable_shift; inf where the pairs cannot reach p < 0.05; NaN
    where the calibrated test did not relabel within seed pairs because the two sides' seeds
    differ). Candidates with fewer than MIN_SEEDS such pairs are left out."""
    import pandas as pd

    from activefoam import power
    f = study.fitness or {}
    rows = []
    for cand, ref_runs, cand_runs in _fitness_pairs(study, runs):
        if "seed" not in ref_runs or "seed" not in cand_runs:
            continue
        rs, cs = [int(x) for x in ref_runs["seed"]], [int(x) for x in cand_runs["seed"]]
        calibrated_in_pairs = _calibration_runs(_with_results(ref_runs, f["metrics"]),
                                                _with_results(cand_runs, f["metrics"]),
                                                len(f["metrics"]))[2]
        for m in f["metrics"]:
            d = trends.paired_difference(ref_runs[m], cand_runs[m], rs, cs)
            if d.n < trends.MIN_SEEDS:
                continue
            k = (power.paired_detectable_shift(d.n, len(f["metrics"])) if calibrated_in_pairs
                 else math.nan)
            rows.append({"candidate": _point_label(cand, f["key"]), "metric": m,
                         "pairs": d.n, "paired_diff": d.diff, "paired_lo": d.lo,
                         "paired_hi": d.hi, "coverage": d.coverage, "higher": d.higher,
                         "lower": d.lower, "sd_diff": d.sd,
                         "found_80": k * d.sd if math.isfinite(k) else k})
    return pd.DataFrame(rows, columns=["candidate", "metric", "pairs", "paired_diff", "paired_lo",
                                       "paired_hi", "coverage", "higher", "lower", "sd_diff",
                                       "found_80"])


PAIRED_NOTE = """
**Seed by seed.** Where both settings ran the same seeds, each seed's two runs start from the
same prepared spheroids, so their difference is free of the seed-to-seed spread that the
difference of medians above carries: `paired_diff` is the median over the seeds of candidate −
reference, `higher` / `lower` the pairs that went up or down, and [`paired_lo`, `paired_hi`] a
distribution-free interval of that median (order statistics of the pairs' differences) with its
exact `coverage`: 95 % or more from 6 pairs on, the range of the differences below that (75 %
with 3 pairs, 94 % with 5), where a bootstrap would claim 95 % for the same range. An interval
that excludes 0 on one metric is not the calibrated verdict (eight metrics are read at once;
the min-p line above corrects for that); it says how large and how regular the effect is.
`found_80` is what the calibrated reading could have missed: the shift of that metric alone
(the others unshifted) that its test finds 80 % of the time with these pairs — 1.5 SDs of the
differences with 10 pairs and eight metrics (modelled as normal and independent;
`activefoam.power.paired_detectable_shift`), `inf` where the pairs cannot reach p < 0.05 at all
(with eight metrics, 8 pairs or fewer: each metric's extreme labelling ties at the least p, so
the least p is about 2·8/2ⁿ), empty where the two sides' seeds differ and the test split the
runs freely. Its SD comes from the same few pairs (±25 % with 10, more with fewer): a "no
difference found" rules out shifts of about that size, not smaller ones.
"""


def _fitness_failures(study: Study, runs: Any) -> List[str]:
    """One line per reference and candidate point with runs that failed in the simulation: the
    seed, the failure's kind and the simulated time it ended at."""
    if "state" not in runs:
        return []
    f = study.fitness or {}
    import pandas as pd
    lines: List[str] = []
    points = []
    for cand, ref_runs, own in _fitness_pairs(study, runs):
        points += [("reference", f"{f['key']} = {f['reference']}", ref_runs),
                   ("candidate", _point_label(cand, f["key"]), own)]
    for role, label, r in points:
        bad = r[(r["state"] == "failed")
                & r.get("failure_kind", pd.Series("", index=r.index)).isin(SIMULATION_FAILURES)]
        if not len(bad):
            continue
        what = []
        for _, b in bad.sort_values("seed").iterrows() if "seed" in bad else bad.iterrows():
            kind = b.get("failure_kind") or "failed"
            t = b.get("t_end_s")
            at = f" at {t:,.0f} s".replace(",", " ") if pd.notna(t) else ""
            what.append(f"seed {int(b['seed'])} ({kind}{at})" if "seed" in b else f"{kind}{at}")
        line = f"- {role} `{label}`: {len(bad)} failed — " + ", ".join(what)
        if line not in lines:
            lines.append(line)
    return lines


def render_fitness(study: Study, data: Data, out: Path) -> List[Path]:
    import matplotlib.pyplot as plt
    import numpy as np
    f = study.fitness or {}
    table = fitness_table(study, data.runs)
    table.to_csv(out / "fitness.csv", index=False)
    verdicts = []
    for cand, g in table.groupby("candidate", sort=False) if len(table) else []:
        judged = g[g["fit"] != "—"]
        if len(judged) < len(g):
            verdicts.append((cand, f"- `{cand}`: not decided — "
                                   f"{len(g) - len(judged)} of {len(g)} metrics lack runs"))
        elif (judged["fit"] == "yes").all():
            verdicts.append((cand, f"- `{cand}`: **fit** — every difference of medians "
                                   f"is below half the seed-to-seed IQR"))
        else:
            bad = ", ".join(judged[judged["fit"] == "no"]["metric"])
            verdicts.append((cand, f"- `{cand}`: **not fit** — {bad}"))
    calibration = fitness_calibration(study, data.runs)
    calibration.to_csv(out / "fitness-calibration.csv", index=False)
    by_candidate = {c["candidate"]: c for _, c in calibration.iterrows()}
    lines = []
    for cand, verdict in verdicts:
        lines.append(verdict)
        c = by_candidate.get(cand)
        if c is None or "p_value" not in c or not (c["p_value"] == c["p_value"]):
            continue
        if c["p_value"] < 0.05:
            reading = (f"**a difference** (p < 0.05): {c['most_different']} differs more than "
                       "relabelling the runs makes it")
        elif c["smallest_p"] >= 0.05:
            reading = (f"no difference found, and none could be: the smallest p "
                       f"{int(c['relabellings'])} relabellings allow is {c['smallest_p']:.3g}")
        else:
            reading = ("no difference found (not: none exists; the shifts it finds 80 % of the "
                       "time: `found_80`, seed by seed below)")
        how = ("within each seed's pair" if c["paired"] else "splits of the pooled runs") + (
            "" if c["exact"] else ", a sample")
        if c["paired"] and (c.get("n_relabelled", c["n"]) < c["n"]
                            or c.get("n_relabelled_ref", c["n_ref"]) < c["n_ref"]):
            how += (f": the {int(c['n_relabelled'])} seeds both sides ended, "
                    f"{int(c['n_ref'] - c['n_relabelled_ref'])} reference and "
                    f"{int(c['n'] - c['n_relabelled'])} candidate runs without a partner left out")
        lines.append(
            f"  - calibrated: p = {c['p_value']:.3g} over {int(c['relabellings'])} "
            f"relabellings ({how}; min-p over {int(c['metrics'])} metrics), the most different "
            f"{c['most_different']} (its own p = {c['p_' + c['most_different']]:.3g}); the "
            f"rule's worst ratio |Δ|/(IQR/2) is {c['worst_ratio']:.3g} ({c['worst_metric']}) "
            f"and it calls {100 * c['rule_pass_rate_equal']:.1f} % of the relabellings fit — "
            f"{reading}")
    failed = _fitness_failures(study, data.runs)
    if failed:
        lines.append("\nRuns that failed in the simulation (a candidate's own failure disqualifies "
                     "it; a reference's is a failure of the reference step, and the candidates "
                     "are read against the references that ended):\n")
        lines += failed
    show = table.drop(columns=["why"]) if len(table) else table
    paired = fitness_paired(study, data.runs)
    paired.to_csv(out / "fitness-paired.csv", index=False)
    seed_by_seed = ("\n## Seed by seed\n\n" + _markdown(paired) + "\n" + PAIRED_NOTE
                    if len(paired) else "")
    (out / "fitness.md").write_text(
        f"# {study.title}: fitness against `{f['key']} = {f['reference']}`\n\n"
        + "\n".join(lines) + "\n\n" + _markdown(show) + "\n" + CALIBRATION_NOTE
        + seed_by_seed)
    # θ(t) ensemble bands of each value of the key.
    fig, ax = plt.subplots(figsize=(7, 4))
    points = [p for p in study.points() if f["key"] in p]
    for c, p in zip(plt.cm.tab10(np.arange(len(points))), points):
        sel = _runs_of_point(data.runs, p, study.swept_keys())
        t, med, q25, q75 = _series(study, data, sel, "theta_deg")
        if len(t):
            ax.plot(t / 3600, med, color=c, label=f"{_point_label(p, f['key'])} (median, IQR "
                    f"over {int((sel['state'] == 'succeeded').sum())} seeds)")
            ax.fill_between(t / 3600, q25, q75, color=c, alpha=0.25, lw=0)
    ax.set(xlabel="t (h)", ylabel="θ (°)")
    # A study's title is often longer than the axes: wrapped, so that none of it is cut off.
    ax.set_title(textwrap.fill(f"{study.title}: θ(t) ensembles", 80), fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / f"{study.name}-theta-bands.png", dpi=110)
    plt.close(fig)
    return [out / "fitness.csv", out / "fitness-calibration.csv", out / "fitness-paired.csv",
            out / "fitness.md",
            out / f"{study.name}-theta-bands.png"]


# ---- command line ----------------------------------------------------------------------------

def _client(args: Any) -> Any:
    from activefoam.client import Client
    return Client(args.server, token=_token(args), tls_ca=args.tls_ca)


def _token(args: Any) -> Optional[str]:
    if args.token_file:
        return Path(args.token_file).read_text().strip()
    return None


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python3 -m activefoam.study",
        description="Run a study file through foamd (resumable) and report it from the store.")
    ap.add_argument("--server", default=None, help="foamd address (default FOAM_SERVER or "
                    "127.0.0.1:50051)")
    ap.add_argument("--token-file", default=None, help="bearer token file (default FOAM_TOKEN)")
    ap.add_argument("--tls-ca", default=None, help="PEM of foamd's certificate or CA")
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
                      "not submitted again, and are reported with the store's")
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
    args = ap.parse_args(argv)
    try:
        if args.cmd in ("save-store", "restore-store"):
            from activefoam import store_copy
            try:
                if args.cmd == "save-store":
                    m = store_copy.save(args.db, args.dir, engine=args.engine,
                                        snapshots=not args.without_snapshots,
                                        engine_commit=args.engine_commit)
                else:
                    m = store_copy.restore(args.dir, args.db, engine=args.engine,
                                           engine_changed_ok=args.engine_changed)
            except store_copy.StoreCopyError as e:
                raise StudyError(str(e)) from None
            states = ", ".join(f"{n} {s}" for s, n in m["by_state"].items())
            print(f"{args.cmd}: {m['jobs']} jobs ({states}), "
                  f"{m['checkpoints']} checkpoints, {m['spheroids']} prepared spheroids; "
                  f"engine {m['engine']}, saved {m['saved_utc']}", file=sys.stderr)
            return 0
        if args.cmd == "verdicts":
            from activefoam import verdicts
            def rel(x: str) -> str:  # as typed from the checkout, not this machine's paths
                r = os.path.relpath(x)
                return x if r.startswith("..") else r
            command = (f"scripts/study.sh verdicts {rel(args.study)} --data {rel(args.data)} "
                       f"--out {rel(args.out)}")
            for f in verdicts.write(verdicts.load(args.study), args.data, args.out,
                                    command=command):
                print(f)
            return 0
        study = load(args.study)
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
        carried = None
        if getattr(args, "with_data", None):
            if args.cmd == "report" and args.from_data:
                raise StudyError("--with-data: not with --from-data (which reads no store)")
            carried = carried_runs(study, args.with_data)
            print(f"study {study.name}: {len(carried.rows)} ended runs in {args.with_data}",
                  file=sys.stderr)
        if args.cmd == "run":
            if args.retry_failed and args.retry_kinds:
                raise StudyError("--retry-failed reruns every failure kind: not with "
                                 "--retry-kinds")
            retry = True if args.retry_failed else _retry_kinds(args.retry_kinds)
            with _client(args) as c:
                # Stale jobs first: a changed step must not leave the old one's queue running.
                cancel_stale(study, c, args.cancel_stale)
                n_new, n_held = submit_missing(study, c, retry_failed=retry,
                                               carried=carried)
                print(f"study {study.name}: {n_new} runs submitted, {n_held} already in the "
                      f"store{' or the data' if carried else ''} (tag {study.tag})",
                      file=sys.stderr)
                submit_diagnoses(study, c)
                if args.no_wait:
                    return 0
                counts = wait(study, c, poll_s=args.poll, carried=carried)
                print(f"study {study.name}: " + ", ".join(f"{n} {s}" for s, n in
                                                         sorted(counts.items())), file=sys.stderr)
                if args.report:
                    _report(study, c, Path(args.report), carried)
                return 1 if counts.get("failed", 0) or counts.get("cancelled", 0) else 0
        out = Path(args.out) if args.out else study.path.parent / f"{study.name}-report"
        if args.from_data:
            data = load_data(study, args.from_data)
            for f in render(study, data, out):
                print(f)
            return 0
        with _client(args) as c:
            _report(study, c, out, carried)
        return 0
    except ValueError as e:  # StudyError, or a spec foamd refused
        print(f"error: {e}", file=sys.stderr)
        return 2
    except PermissionError as e:
        print(f"error: {e}", file=sys.stderr)
        return 4
    except BrokenPipeError:  # a ConnectionError too, but of stdout (`check | head`)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except ConnectionError as e:
        print(f"error: {e} (is foamd running? --server / FOAM_SERVER)", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print("\ninterrupted: the submitted jobs go on in foamd; run the same command again to "
              "follow them (nothing is submitted twice)", file=sys.stderr)
        return 130


def _report(study: Study, client: Any, out: Path, carried: Optional[Carried] = None) -> None:
    data_dir = collect(study, client, out / "data", carried)
    data = load_data(study, data_dir)
    for f in render(study, data, out):
        print(f)


if __name__ == "__main__":
    sys.exit(main())
