"""The verdict table: the supplement's trend statements, each judged on a study's committed data.

A verdicts file (TOML, `studies/verdicts.toml`) lists the statements; each names the study that
measures it, the metric, the two ensembles it compares (`low` → `high`: the effect is
median(high) − median(low)), what the supplement says (`expect`) and where it says it:

    [[trend]]
    figure = "Fig. 9C"
    statement = "θ_eq increases with τ_p"
    source = "caption"            # caption | implied | none (what the supplement states)
    study = "fig9-reduced.toml"   # relative to the verdicts file
    metric = "theta_eq_deg"       # a study metric (activefoam.study.METRICS) or "failed"
    expect = "increase"           # increase | decrease | none | below | above | report
    low = { "cells.tau_p_s" = 150 }
    high = { "cells.tau_p_s" = 2400 }
    per = "cells.alpha"           # optional: one row per value of this key
    band_rel = 0.25               # "none": |effect| ≤ band_rel × |median(low)| (or band, absolute)
    value = 90                    # "below" / "above": the median's interval against this value

`below` / `above` judge one ensemble (`high`) against a level. `report` shows the effect with no
verdict (the supplement draws it but states no trend). The metric `failed` is 1 for a run that
failed in the simulation itself, 0 for one that succeeded (the supplement's hatched cells); a
failure that a diagnosis rerun ran past (the study file's [[diagnose]]) is left out.

The rules are activefoam.trends' (no verdict from fewer than 3 runs a side). A study whose data
folder (DATA/NAME/data, written by `study report --out DATA/NAME`) is missing gives its rows the
verdict "not run yet".
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

try:
    import tomllib  # Python >= 3.11
except ModuleNotFoundError:  # pragma: no cover - Python 3.9/3.10: the tomli package
    import tomli as tomllib  # type: ignore

from activefoam import trends
from activefoam.inputs import SPEC_MAX_BYTES, read_text
from activefoam.study import studyfile as sf
from activefoam.study.data import _ran_past, load_data
from activefoam.study.outputs import folder, to_csv, write_text

TREND_KEYS = {"figure", "statement", "source", "study", "metric", "expect", "low", "high", "per",
              "band", "band_rel", "value"}
EXPECT = ("increase", "decrease", "none", "below", "above", "report")
SOURCES = ("caption", "implied", "none")


@dataclass
class TrendSpec:
    index: int
    figure: str
    statement: str
    source: str
    study: sf.Study
    metric: str
    expect: str
    low: Dict[str, Any] = field(default_factory=dict)
    high: Dict[str, Any] = field(default_factory=dict)
    per: str = ""
    band: Optional[float] = None
    band_rel: Optional[float] = None
    value: Optional[float] = None


def load(path: os.PathLike) -> List[TrendSpec]:
    """Reads and checks a verdicts file; StudyError names the entry and key."""
    p = Path(path)
    if not p.is_file():
        raise sf.StudyError(f"verdicts: no such file {str(p)!r}")
    try:
        text = read_text(p, SPEC_MAX_BYTES, "verdicts", regular=True)
    except ValueError as e:  # over 1 MiB, or not UTF-8
        raise sf.StudyError(str(e)) from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise sf.StudyError(f"verdicts: {p}: not TOML: {e}") from None
    sf._unknown(doc, {"trend"}, "")
    items = doc.get("trend")
    if not isinstance(items, list) or not items:
        raise sf.StudyError("trend: at least one [[trend]] table")
    studies: Dict[Path, sf.Study] = {}
    out = []
    for i, t in enumerate(items):
        w = f"trend[{i}]"
        if not isinstance(t, dict):
            raise sf.StudyError(f"{w}: a table")
        sf._unknown(t, TREND_KEYS, f"{w}.")
        for k in ("figure", "statement", "study", "metric", "expect"):
            if not isinstance(t.get(k), str) or not t[k]:
                raise sf.StudyError(f"{w}.{k}: a non-empty string, got {t.get(k)!r}")
        if t["expect"] not in EXPECT:
            raise sf.StudyError(f"{w}.expect: one of {', '.join(EXPECT)}, got {t['expect']!r}")
        source = t.get("source", "caption")
        if source not in SOURCES:
            raise sf.StudyError(f"{w}.source: one of {', '.join(SOURCES)}, got {source!r}")
        if t["metric"] != "failed" and t["metric"] not in sf.METRICS:
            raise sf.StudyError(f"{w}.metric: 'failed' or one of {', '.join(sf.METRICS)}"
                                f"{sf._closest(t['metric'], list(sf.METRICS) + ['failed'])}, "
                                f"got {t['metric']!r}")
        sp = (p.parent / t["study"]).resolve()
        if sp not in studies:
            try:
                studies[sp] = sf.load(sp)
            except sf.StudyError as e:
                raise sf.StudyError(f"{w}.study: {e}") from None
        study = studies[sp]
        keys = study.swept_keys()
        spec = TrendSpec(i, t["figure"], t["statement"], source, study, t["metric"], t["expect"])
        for side in ("low", "high"):
            v = t.get(side, {})
            if not isinstance(v, dict):
                raise sf.StudyError(f"{w}.{side}: a table of KEY = value")
            for k in v:
                if k not in keys:
                    raise sf.StudyError(f"{w}.{side}.{k}: not a grid key of {study.name}"
                                        f"{sf._closest(k, keys)}; grid keys: {', '.join(keys)}")
            setattr(spec, side, dict(v))
        if not spec.high:
            raise sf.StudyError(f"{w}.high: the ensemble judged (a table of KEY = value)")
        if spec.expect in ("increase", "decrease", "none", "report") and not spec.low:
            raise sf.StudyError(f"{w}.low: the ensemble compared against (a table of KEY = value)")
        per = t.get("per", "")
        if per and per not in keys:
            raise sf.StudyError(f"{w}.per: not a grid key of {study.name}{sf._closest(per, keys)}")
        spec.per = per
        for k in ("band", "band_rel", "value"):
            if k in t:
                if not isinstance(t[k], (int, float)) or isinstance(t[k], bool) or \
                        not math.isfinite(t[k]) or (k != "value" and t[k] < 0):
                    raise sf.StudyError(f"{w}.{k}: a finite number{' ≥ 0' if k != 'value' else ''}"
                                        f", got {t[k]!r}")
                setattr(spec, k, float(t[k]))
        if spec.expect in ("below", "above") and spec.value is None:
            raise sf.StudyError(f"{w}.value: the level that '{spec.expect}' compares with")
        if spec.expect == "none" and spec.band is None and spec.band_rel is None:
            raise sf.StudyError(f"{w}.band: 'none' needs band (absolute) or band_rel (relative to "
                                "the low median)")
        out.append(spec)
    return out


def _select(runs: Any, point: Dict[str, Any]) -> Any:
    sel = runs
    for k, v in point.items():
        if k not in sel:
            return runs.iloc[0:0]
        sel = sel[[sf._same(x, v) for x in sel[k]]]
    return sel


def _numerics_counts(runs: Any) -> Dict[str, Dict[str, int]]:
    """The numerics.* keys these runs were given (their `settings`), each value (as JSON) with
    its number of runs."""
    out: Dict[str, Dict[str, int]] = {}
    if "settings" not in runs:
        return out
    for text in runs["settings"]:
        try:
            d = json.loads(text) if isinstance(text, str) else {}
        except ValueError:
            continue
        for k, v in d.items():
            if k.startswith("numerics."):
                c = out.setdefault(k, {})
                c[json.dumps(v)] = c.get(json.dumps(v), 0) + 1
    return out


def _numerics(runs: Any, point: Dict[str, Any]) -> Dict[str, set]:
    """The numerics.* keys the runs at this point were given, each with the set of values it
    took: a trend read across points of different steps (a study that gives some points their
    own step) says so."""
    return {k: set(c) for k, c in _numerics_counts(_select(runs, point)).items()}


def numerics_differ(runs: Any, low: Dict[str, Any], high: Dict[str, Any]) -> str:
    """'' when both ensembles ran the same numerics, else the keys that differ, low → high."""
    a, b = _numerics(runs, low), _numerics(runs, high)
    if not a or not b:
        return ""
    parts = []
    for k in sorted(set(a) | set(b)):
        va, vb = a.get(k, {"(default)"}), b.get(k, {"(default)"})
        if va != vb:
            parts.append(f"{k} {'/'.join(sorted(va))} → {'/'.join(sorted(vb))}")
    return "; ".join(parts)


def _runs_by_study(items: List[TrendSpec], data_root: os.PathLike) -> Dict[str, Any]:
    """Each study's runs (runs.csv of its report's data), None where it has none yet."""
    out: Dict[str, Any] = {}
    for t in items:
        if t.study.name not in out:
            d = Path(data_root) / t.study.name / "data"
            out[t.study.name] = load_data(t.study, d).runs if (d / "runs.csv").is_file() \
                else None
    return out


def numerics_by_study(items: List[TrendSpec], data_root: os.PathLike,
                      runs_by_study: Optional[Dict[str, Any]] = None) -> List[str]:
    """Per study with data, the numerics.* settings its runs were given, each value with its
    count of runs: which step and contact law a verdict rests on (studies may give some points
    a step of their own). A key set alike in every run shows one value."""
    out = []
    if runs_by_study is None:
        runs_by_study = _runs_by_study(items, data_root)
    for name, runs in runs_by_study.items():
        if runs is None:
            continue
        if "state" in runs:
            runs = runs[runs["state"].isin(["succeeded", "failed"])]
        counts = _numerics_counts(runs)
        if counts:
            out.append(f"- {name} ({len(runs)} runs): " + "; ".join(
                f"{k} " + ", ".join(f"{v} ({n})" for v, n in sorted(c.items()))
                for k, c in sorted(counts.items())))
    return out


# Metrics of Eq. 1's fit: NaN where it did not converge (an arrested fusion) or its τ_f is longer
# than the run (study.derive_metrics).
EQ1_METRICS = ("theta_eq_deg", "tau_f_s", "tau_f_over_tau_p")


def _values(runs: Any, point: Dict[str, Any], metric: str) -> List[float]:
    sel = _select(runs, point)
    if not len(sel):
        return []
    if metric == "failed":
        failed = _simulation_failed(sel)
        ok = (sel["state"] == "succeeded") & ~_ran_past(sel)
        return [1.0 if f else 0.0 for f, o in zip(failed, ok) if f or o]
    if metric not in sel:
        return []
    return [float(x) for x in sel[metric] if x == x]


def _no_value(runs: Any, point: Dict[str, Any], metric: str) -> int:
    """How many of the point's succeeded runs have no value of the metric (Eq. 1's θ_eq and τ_f
    where the fit did not converge: an arrested fusion has none)."""
    sel = _select(runs, point)
    if metric == "failed" or not len(sel) or metric not in sel:
        return 0
    ok = sel[sel["state"] == "succeeded"]
    return int(ok[metric].isna().sum())


def _simulation_failed(sel: Any) -> Any:
    """Per run: failed in the simulation itself (the supplement's hatched cells). A failure a
    diagnosis rerun ran past (the study file's [[diagnose]]) is those numerics', not the point's: left
    out, as a run that did not end."""
    kind = sel["failure_kind"].fillna("") if "failure_kind" in sel else ""
    return ((sel["state"] == "failed") & kind.isin(sf.SIMULATION_FAILURES)
            & ~_ran_past(sel))


def _failed_and_pending(runs: Any, point: Dict[str, Any]) -> Tuple[int, int]:
    """The point's runs that failed in the simulation and those not ended yet (queued or
    running): why a side of a row has fewer runs than seeds — the supplement's hatched cells,
    or runs still to come."""
    sel = _select(runs, point)
    if not len(sel) or "state" not in sel:
        return 0, 0
    pending = sel["state"].isin(["queued", "running"])
    return int(_simulation_failed(sel).sum()), int(pending.sum())


def _beyond_run(runs: Any, point: Dict[str, Any], metric: str) -> int:
    """Of _no_value's runs, those whose Eq. 1 fit converged with τ_f longer than the run."""
    sel = _select(runs, point)
    if metric not in EQ1_METRICS or not len(sel) or "eq1_beyond_run" not in sel:
        return 0
    ok = sel[sel["state"] == "succeeded"]
    return int(ok["eq1_beyond_run"].fillna(False).astype(bool).sum())


def _median_interval(x: List[float]) -> trends.Difference:
    """The median of one ensemble with its percentile-bootstrap interval (as a difference
    against 0)."""
    return trends.diff_of_medians([0.0], x)


def _fmt(v: float) -> str:
    if v is None or not np.isfinite(v):
        return "—"
    return f"{v:.3g}"


def evaluate(items: List[TrendSpec], data_root: os.PathLike,
             runs_by_study: Optional[Dict[str, Any]] = None) -> Any:
    """One row per statement (and value of `per`): the two ensembles' medians and counts, the
    effect with its 95 % interval, and the verdict."""
    import pandas as pd
    rows = []
    if runs_by_study is None:
        runs_by_study = _runs_by_study(items, data_root)
    for t in items:
        runs = runs_by_study[t.study.name]
        pers: List[Any] = [None]
        if t.per:
            pers = []
            for pt in t.study.points():
                v = pt.get(t.per)
                if v is not None and not any(sf._same(v, w) for w in pers):
                    pers.append(v)
        for pv in pers:
            low = dict(t.low, **({t.per: pv} if t.per else {}))
            high = dict(t.high, **({t.per: pv} if t.per else {}))
            row = {"figure": t.figure, "statement": t.statement, "source": t.source,
                   "study": t.study.name, "metric": t.metric, "expect": t.expect,
                   "at": f"{t.per} = {pv}" if t.per else "",
                   "value": t.value,  # a level row names its level even before it has runs
                   "low": ", ".join(f"{k} = {v}" for k, v in t.low.items()),
                   "high": ", ".join(f"{k} = {v}" for k, v in t.high.items())}
            if runs is None:
                row.update(verdict="not run yet", n_low=0, n_high=0)
                rows.append(row)
                continue
            xl, xh = _values(runs, low, t.metric), _values(runs, high, t.metric)
            level = t.expect in ("below", "above")  # one ensemble, judged against a level
            row.update(no_value_low=0 if level else _no_value(runs, low, t.metric),
                       no_value_high=_no_value(runs, high, t.metric),
                       beyond_run_low=0 if level else _beyond_run(runs, low, t.metric),
                       beyond_run_high=_beyond_run(runs, high, t.metric))
            for side, pt in (("low", low), ("high", high)):
                if level and side == "low":
                    continue
                nf, npend = _failed_and_pending(runs, pt)
                row.update({f"failed_{side}": nf, f"pending_{side}": npend})
            row.update(n_low=len(xl), n_high=len(xh), median_low=trends.median(xl),
                       median_high=trends.median(xh),
                       numerics_differ=numerics_differ(runs, low, high)
                       if t.expect not in ("below", "above") else "")
            if t.expect in ("below", "above"):
                m = _median_interval(xh)
                row.update(effect=m.diff, lo=m.lo, hi=m.hi)
                if len(xh) < trends.MIN_SEEDS:
                    verdict = "too few runs"
                elif (m.hi < t.value) if t.expect == "below" else (m.lo > t.value):
                    verdict = "agrees"
                elif (m.lo > t.value) if t.expect == "below" else (m.hi < t.value):
                    verdict = "disagrees"
                else:
                    verdict = "not resolved"
            else:
                band = t.band if t.band is not None else (
                    (t.band_rel or 0.0) * abs(trends.median(xl)) if xl else 0.0)
                tr = trends.trend(xl, xh, "none" if t.expect == "report" else t.expect,
                                  band=band)
                row.update(effect=tr.diff.diff, lo=tr.diff.lo, hi=tr.diff.hi)
                if t.expect == "none":
                    row["band"] = band
                verdict = "no statement" if (t.expect == "report" and
                                             tr.verdict != "too few runs") else tr.verdict
            row["verdict"] = verdict
            rows.append(row)
    return pd.DataFrame(rows)


def markdown(table: Any) -> str:
    head = ["figure", "statement", "at", "metric", "low → high", "median low (n)",
            "median high (n)", "effect [95 %]", "verdict"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for _, r in table.iterrows():
        expect = r["expect"]
        if expect in ("below", "above"):
            cmp = f"{r['high']} ({expect} {_fmt(r.get('value'))})"
            eff = f"median {_fmt(r.get('effect'))} [{_fmt(r.get('lo'))}, {_fmt(r.get('hi'))}]"
        else:
            cmp = f"{r['low']} → {r['high']}"
            eff = f"{_fmt(r.get('effect'))} [{_fmt(r.get('lo'))}, {_fmt(r.get('hi'))}]"
            if expect == "none" and r.get("band") == r.get("band"):
                eff += f" (band ±{_fmt(r.get('band'))})"
        src = "" if r["source"] == "caption" else f" ({r['source']})"
        verdict = r["verdict"]
        if verdict in ("agrees", "disagrees"):
            verdict = f"**{verdict}**"
        missing = [f"{int(r.get(f'no_value_{side}') or 0)} {side}" for side in ("low", "high")
                   if (r.get(f"no_value_{side}") or 0) > 0]
        if verdict == "too few runs" and missing:
            if r["metric"] in EQ1_METRICS:
                beyond = sum(int(r.get(f"beyond_run_{side}") or 0) for side in ("low", "high"))
                total = sum(int(r.get(f"no_value_{side}") or 0) for side in ("low", "high"))
                why = ("Eq. 1 did not converge" if not beyond else
                       "Eq. 1's τ_f longer than the run" if beyond == total else
                       f"Eq. 1 did not converge ({total - beyond}) or its τ_f is longer than "
                       f"the run ({beyond})")
            else:
                why = "the metric has no value"
            verdict += f" (succeeded runs without a value: {', '.join(missing)}: {why})"
        if verdict == "too few runs" and r["metric"] != "failed":
            for what, key in (("failed in the simulation", "failed"),
                              ("not ended yet", "pending")):
                n = [f"{int(r.get(f'{key}_{side}') or 0)} {side}" for side in ("low", "high")
                     if (r.get(f"{key}_{side}") or 0) > 0]
                if n:
                    verdict += f" ({what}: {', '.join(n)})"
        differ = r.get("numerics_differ")
        if isinstance(differ, str) and differ:
            verdict += f" (the two ensembles ran different numerics: {differ})"
        lines.append("| " + " | ".join([
            r["figure"], r["statement"] + src, r["at"] or "—", r["metric"], cmp,
            f"{_fmt(r.get('median_low'))} ({int(r.get('n_low', 0) or 0)})"
            if expect not in ("below", "above") else "—",
            f"{_fmt(r.get('median_high'))} ({int(r.get('n_high', 0) or 0)})", eff, verdict])
            + " |")
    return "\n".join(lines) + "\n"


def _numerics_section(items: List[TrendSpec], data_root: os.PathLike,
                      runs_by_study: Dict[str, Any]) -> str:
    lines = numerics_by_study(items, data_root, runs_by_study)
    if not lines:
        return ""
    return ("\n## The numerics each study ran\n\nThe `numerics.*` settings of each study's ended "
            "runs, each value with its number of runs (docs/science/presets.md says why):\n\n"
            + "\n".join(lines) + "\n")


def _figures_section(items: List[TrendSpec], data_root: os.PathLike, out: Path) -> str:
    """Each judged study's report figures (DATA/NAME/NAME-trends.png, -curves.png), linked from
    the table's folder: the verdicts read beside what they were drawn from."""
    parts, seen = [], set()
    for t in items:
        name = t.study.name
        if name in seen:
            continue
        seen.add(name)
        folder = Path(data_root) / name
        pngs = [folder / f"{name}-{kind}.png" for kind in ("trends", "curves")]
        pngs = [p for p in pngs if p.exists()]
        if not pngs:
            continue
        parts.append(f"### {t.study.title or name}\n\n" + "\n\n".join(
            f"![{name} {p.stem.rsplit('-', 1)[-1]}]"
            f"({Path(os.path.relpath(p, out)).as_posix()})" for p in pngs) + "\n")
    if not parts:
        return ""
    return ("\n## The figures\n\nEach judged study's trends (median and IQR over seeds, failed "
            "runs in red) and curves, from its report folder:\n\n" + "\n".join(parts))


def write(items: List[TrendSpec], data_root: os.PathLike, out: os.PathLike,
          command: str = "") -> List[Path]:
    runs_by_study = _runs_by_study(items, data_root)
    table = evaluate(items, data_root, runs_by_study)
    o = folder(out)
    to_csv(table, o / "verdicts.csv", index=False)
    counts = table["verdict"].value_counts()
    summary = ", ".join(f"{n} {v}" for v, n in counts.items())
    write_text(
        o / "verdicts.md",
        "# The supplement's trend statements, judged\n\n"
        f"{len(table)} rows: {summary}.\n\n"
        "Effect: median(high) − median(low) over seeds with its percentile-bootstrap 95 % "
        "interval; *agrees* when the interval excludes 0 on the supplement's side (for "
        "`none`: lies within the band; for `below`/`above`: the median's interval lies on "
        "the stated side of the level), *disagrees* when it excludes it on the other, *not "
        "resolved* otherwise; no verdict from fewer than 3 runs a side (such a row says how "
        "many of a side's runs failed in the simulation — the supplement's hatched cells — "
        "or have not ended). Source: *caption* — "
        "stated in the supplement's figure caption; *implied* — follows from a stated "
        "result (named in the statement); *none* — drawn, no trend stated.\n\n"
        + (f"Regenerated from the studies' committed data by `{command}`.\n\n"
           if command else "")
        + markdown(table) + _numerics_section(items, data_root, runs_by_study)
        + _figures_section(items, data_root, o))
    return [o / "verdicts.md", o / "verdicts.csv"]
