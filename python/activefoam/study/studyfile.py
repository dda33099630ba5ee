"""The study file: its TOML format, the checks that name a bad key, and the runs it asks for.

A study is a base spec, the keys set on top of it ([spec]), grids of keys to sweep ([[grid]]),
seeds and a preset; a run is one (grid point, seed). [fitness] compares settings of one key,
[[share]] takes another study's runs at a common point; a run that failed in the simulation is
rerun once with other numerics, by the tool's own diagnoses or the file's [[diagnose]] tables
(docs/usage.md and docs/science/README.md describe the format).
"""

from __future__ import annotations

import difflib
import hashlib
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

try:
    import tomllib  # Python >= 3.11
except ModuleNotFoundError:  # pragma: no cover - Python 3.9/3.10: the tomli package
    import tomli as tomllib  # type: ignore

from activefoam.client import flatten
from activefoam.inputs import SPEC_MAX_BYTES, read_text


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
              "by_label", "priority", "scale", "diagnose", "columns", "curves"}


FITNESS_KEYS = {"key", "reference", "metrics"}


TOP_KEYS = {"study", "spec", "grid", "fitness", "share", "diagnose"}


DIAGNOSE_KEYS = {"name", "title", "spec", "kinds"}


SHARE_KEYS = {"file", "this", "that", "seeds"}


PRESETS = {"standard", "reference"}


# The failures of the step, which a finer one may cure. Not a failed preparation: it runs at its
# own step (scene.prep_dt_s) with the solver settings fixed (spheroidPrepSpec), so a finer step
# of the run prepares the same aggregates; nor an interpenetration where the run had no keep-out
# (the keep-out diagnosis's, below).
STEP_FAILURES = ["volume-drift", "inverted-triangle", "non-finite", "cg-not-converged",
                 "contact-oscillation", "step-error"]


# The next finer step after a run's preset (its resolved numerics.preset): name, the keys set on
# top of the run's, title. After `reference` (Δt 0.25 s) the supplement's own Δt.
FINER_STEP = {
    "standard": ("reference-step", {"numerics.preset": "reference"},
                 "0.25 s / 1e-3 under the law"),
    "reference": ("supplement-step", {"numerics.dt_s": 0.1}, "Δt 0.1 s, the supplement's"),
}


# What foamd resolves for the keys the built-in diagnoses read where neither the base, the study
# nor a preset sets them (foam-run --keys). Only a report rendered without foamd reads them (its
# list of the diagnoses); with foamd each run's resolved spec is read, and a test holds the two
# equal.
ENGINE_DEFAULTS = {"numerics.preset": "standard", "numerics.max_penetration_um": 1.0,
                   "numerics.remesh_keep_out_um": 0.0}


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
# only where some run has one. The MSRD less the aggregate's rigid turn: near the jam a doublet
# turning as a body passes r² with no cell changing its neighbours.
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


def _closest(word: str, known: Sequence[str]) -> str:
    m = difflib.get_close_matches(word, list(known), n=1)
    return f" (did you mean {m[0]!r}?)" if m else ""


def _unknown(keys, known, where: str) -> None:
    for k in keys:
        if k not in known:
            raise StudyError(f"{where}{k}: unknown key{_closest(k, sorted(known))}; known: "
                             f"{', '.join(sorted(known))}")


def spec_keys() -> frozenset:
    """Every key a spec may set, as foam-run --keys lists them (and the earlier switches foamd
    still reads): from the generated SceneSpec message, whose fields mirror the key table —
    scene and scene.kind, the top-level numbers, cells.*, numerics.*, accuracy.*, observe.*, each
    scene's [scene] keys, and prepare.cells.*, prepare.numerics.* (foamd names those of them the
    preparation cannot take)."""
    from activefoam.v1 import scene_pb2
    keys = {"scene", "scene.kind"}

    def table(prefix: str, message: Any) -> None:
        for g in message.fields:
            if g.message_type is None:
                keys.add(f"{prefix}{g.name}")
            else:
                table(f"{prefix}{g.name}.", g.message_type)

    for f in scene_pb2.SceneSpec.DESCRIPTOR.fields:
        if f.message_type is None:
            keys.add(f.name)
            continue
        table("scene." if f.containing_oneof is not None else f"{f.name}.", f.message_type)
    return frozenset(keys)


def _spec_key(where: str, key: str) -> None:
    """`check` let a misspelt key through (a grid of cells.bogus), which `run` then had refused
    by foamd after the first submissions."""
    known = spec_keys()
    if key not in known:
        raise StudyError(f"{where}: unknown spec key{_closest(key, sorted(known))} (foam-run "
                         "--keys lists them)")


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
    """A run that failed in the simulation with one of `kinds` is rerun once with `spec`'s keys
    set on top of its own (a finer step, a remesher fix), tagged diag:NAME: a rerun that runs to
    the end says the failure was those numerics', not the point's. The built-in ones
    (builtin_diagnoses), or a study file's [[diagnose]] tables instead."""
    name: str
    spec: Dict[str, Any]
    kinds: List[str]
    title: str = ""


def builtin_diagnoses(spec: Dict[str, Any]) -> List[Diagnosis]:
    """The study tool's diagnoses of a run, from its spec by dotted key (as foamd resolved it;
    a key it lacks is at ENGINE_DEFAULTS): an interpenetration is rerun with the remesher's
    keep-out at the interpenetration guard's depth (numerics.max_penetration_um), where the run
    had no keep-out: collapses shallower than the guard are routine and the keep-out lets them
    be, so the rerun is the failed run bit for bit up to the collapse past the guard that failed
    it (docs/numerics.md, "Remeshing"); any other failure of the step (STEP_FAILURES; an
    interpenetration too where the run had the keep-out already) at the next finer step after
    the run's preset (FINER_STEP)."""
    def get(key: str) -> Any:
        v = spec.get(key)
        return ENGINE_DEFAULTS[key] if v is None else v
    out: List[Diagnosis] = []
    step_kinds = list(STEP_FAILURES)
    if get("numerics.remesh_keep_out_um"):
        step_kinds.append("interpenetration")
    else:
        depth = float(get("numerics.max_penetration_um"))
        out.append(Diagnosis("keep-out", {"numerics.remesh_keep_out_um": depth},
                             ["interpenetration"],
                             f"no collapse puts a vertex past the guard's {depth:g} µm inside a "
                             "touching cell"))
    finer = FINER_STEP.get(str(get("numerics.preset")))
    if finer is not None:
        name, keys, title = finer
        out.append(Diagnosis(name, dict(keys), step_kinds, title))
    return out


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
    diagnoses: List[Diagnosis] = field(default_factory=list)   # the file's [[diagnose]] tables
    diagnose: bool = True   # [study] diagnose = false: no diagnosis reruns
    # More sample columns and end-of-run curves for the data folder, beside SAMPLE_COLUMNS and
    # the MSRD: what the runs' probes ([observe] keys) write.
    columns: List[str] = field(default_factory=list)
    curves: List[str] = field(default_factory=list)
    _base_cache: Optional[Dict[str, Any]] = field(default=None, repr=False, compare=False)

    def listed_diagnoses(self) -> List[Diagnosis]:
        """The diagnoses as a report lists them: the file's [[diagnose]] tables, else the
        built-in ones of its runs, each once, read from what the base file and the study set
        (a report from data has no foamd to resolve the runs; where an accuracy target chooses
        a run's preset, the finer step after each preset is listed)."""
        if not self.diagnose:
            return []
        if self.diagnoses:
            return list(self.diagnoses)
        out: List[Diagnosis] = []
        for point in self.points():  # the seed changes no numerics
            spec = {**self._base_keys(), **self.settings(Run(point, self.seeds[0]))}
            presets = [spec.get("numerics.preset")]
            if presets[0] is None and any(k.startswith("accuracy.") for k in spec):
                presets = list(FINER_STEP)
            for preset in presets:
                for d in builtin_diagnoses({**spec, "numerics.preset": preset}):
                    if d not in out:
                        out.append(d)
        return out

    def _base_keys(self) -> Dict[str, Any]:
        """The base spec file's keys, dotted (TOML or JSON, as foamd reads a spec file); none
        where it reads as neither (foamd names the error when a run is submitted)."""
        if not self.base_text:
            return {}
        if self._base_cache is None:
            try:
                doc = tomllib.loads(self.base_text)
            except tomllib.TOMLDecodeError:
                try:
                    doc = json.loads(self.base_text)
                except ValueError:
                    doc = {}
            self._base_cache = flatten(doc) if isinstance(doc, dict) else {}
        return self._base_cache

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


def run_count(grids: Sequence[Dict[str, List[Any]]], n_seeds: int, cap: int = 10**18) -> int:
    """The runs the grids ask for, from their axes' lengths, before any product is built: per
    [[grid]] the product of its axes' lengths, summed, times the seeds (a point two grids share
    counts twice). Stops at `cap` + 1: four axes of 10^5 values cost nothing to count."""
    total = 0
    for g in grids:
        points = 1
        for values in g.values():
            points *= len(values)
            if points * n_seeds > cap:
                return cap + 1
        total += points * n_seeds
        if total > cap:
            return cap + 1
    return total


def _read_text(p: Path, what: str) -> str:
    if not p.exists():
        raise StudyError(f"{what}: no such file {str(p)!r}")
    if not p.is_file():
        raise StudyError(f"{what}: {str(p)!r} is not a regular file")
    try:
        return read_text(p, SPEC_MAX_BYTES, what, regular=True)
    except ValueError as e:
        raise StudyError(str(e)) from None


def load(path: os.PathLike, _shares: bool = True,
         base_root: Optional[os.PathLike] = None) -> Study:
    """Reads and checks a study file; StudyError names the key. Its `base` is read from under
    the study file's folder only, symlinks resolved (a study file from elsewhere cannot send
    /etc/shadow to foamd as a spec), or from under `base_root` where given."""
    p = Path(path)
    text = _read_text(p, "study")
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
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
    for key, taken in (("columns", ["t_s", *SAMPLE_COLUMNS]), ("curves", ["msrd"])):
        names = st.get(key, [])
        if (not isinstance(names, list) or len(names) > 100 or
                not all(isinstance(n, str) and re.fullmatch(r"[a-z][a-z0-9_]{0,63}", n)
                        for n in names)):
            raise StudyError(f"study.{key}: a list of up to 100 {key[:-1]} names (a-z 0-9 _), "
                             f"got {names!r}")
        repeated = sorted({n for n in names if names.count(n) > 1} | (set(names) & set(taken)))
        if repeated:
            raise StudyError(f"study.{key}: {', '.join(repeated)} given twice (or always kept: "
                             f"{', '.join(taken)})")
        setattr(study, key, list(names))
    if "base" in st:
        if not isinstance(st["base"], str):
            raise StudyError(f"study.base: the path of a spec file, got {st['base']!r}")
        base = (p.parent / st["base"]).resolve()
        root = Path(base_root).resolve() if base_root is not None else p.parent.resolve()
        if not base.is_relative_to(root):
            raise StudyError(f"study.base: {str(base)!r} is outside {str(root)!r}"
                             + (" (the study file's folder)" if base_root is None else "")
                             + "; a base is read from under that folder only (--base-root, or "
                             "load(..., base_root=), names another)")
        if not base.is_file():
            raise StudyError(f"study.base: no such spec file {str(base)!r} (relative to the "
                             "study file)")
        study.base, study.base_text = base, _read_text(base, "study.base")
    spec = doc.get("spec", {})
    if not isinstance(spec, dict):
        raise StudyError("spec: a table of spec keys")
    study.spec = {k: _scalar(f"spec.{k}", v) for k, v in flatten(spec).items()}
    for k in study.spec:
        if k != "seed":  # named below
            _spec_key(f"spec.{k}", k)
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
        flat = flatten(g)
        for k, vs in flat.items():
            if k == "seed":
                raise StudyError(f"grid[{i}].seed: seeds belong in study.seeds")
            if not isinstance(vs, list) or not vs:
                raise StudyError(f"grid[{i}].{k}: a non-empty list of values, got {vs!r}")
            flat[k] = [_scalar(f"grid[{i}].{k}", v) for v in vs]
        study.grids.append(flat)
    n = run_count(study.grids, len(study.seeds), cap=10**18)
    if n > MAX_RUNS:
        count = "more than 10^18" if n > 10**18 else str(n)
        raise StudyError(f"{p}: grid: {count} runs ([[grid]] products × {len(study.seeds)} "
                         f"seeds), more than the {MAX_RUNS} a study may hold: split it")
    for i, g in enumerate(study.grids):
        for k in g:
            _spec_key(f"grid[{i}].{k}", k)
    swept = study.swept_keys()
    for key in ("x", "by"):
        v = getattr(study, key)
        if v and v not in swept:
            raise StudyError(f"study.{key}: {v!r} is not a grid key{_closest(v, swept)}; grid "
                             f"keys: {', '.join(swept)}")
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
    switch = st.get("diagnose", True)
    if not isinstance(switch, bool):
        raise StudyError(f"study.diagnose: true (failed runs are rerun by the built-in "
                         f"diagnoses or the [[diagnose]] tables) or false (none), got {switch!r}")
    if not switch and study.diagnoses:
        raise StudyError("study.diagnose: false turns the diagnoses off, but the file has "
                         "[[diagnose]] tables: remove one or the other")
    study.diagnose = switch
    shares = doc.get("share", [])
    if not isinstance(shares, list):
        raise StudyError("share: [[share]] tables (file, this, that)")
    if _shares:
        for i, sh in enumerate(shares):
            study.shares.append(_load_share(study, i, sh, base_root))
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
    flat = {k: _scalar(f"{where}.spec.{k}", v) for k, v in flatten(spec).items()}
    for k in flat:
        _spec_key(f"{where}.spec.{k}", k)
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


def _load_share(study: Study, i: int, sh: Any,
                base_root: Optional[os.PathLike] = None) -> Share:
    """[[share]]: file = another study file (relative to this one), this = one of this study's
    points, that = the same run's point in the other study, seeds (optional) = the seeds of this
    study at which the two are one run (default: all). Both studies must submit the same
    base, [spec] and preset, so that a job of one is a run of the other; the keys each point
    leaves to the base are checked when the runs are matched (foamd resolves the two points to
    one spec, or the share is an error naming the key)."""
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
        other = load(other_path, _shares=False, base_root=base_root)
    except StudyError as e:
        raise StudyError(f"{where}.file: {e}") from None
    for k in ("this", "that"):
        if not isinstance(sh[k], dict) or not sh[k]:
            raise StudyError(f"{where}.{k}: a table of KEY = value, got {sh[k]!r}")
    this = {k: _scalar(f"{where}.this.{k}", v) for k, v in flatten(sh["this"]).items()}
    that = {k: _scalar(f"{where}.that.{k}", v) for k, v in flatten(sh["that"]).items()}
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
