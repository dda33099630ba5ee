"""A study's data: collected from the store into a folder (runs.csv, samples.csv.gz,
msrd.csv.gz, collected.json: what a report is rendered from and what is committed beside it),
read back with the per-run metrics derived from it.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Optional, Tuple

from activefoam.client import state_name
from activefoam.study.matching import (NOOP_TEXT, Carried, _base_sha, _diag_is_noop,
                                       _diag_of_runs, _run_jobs, _takes_carried, diagnosis_entries,
                                       run_diagnoses)
from activefoam.study.outputs import folder, to_csv, write_text
from activefoam.study.studyfile import SAMPLE_COLUMNS, SIMULATION_FAILURES, Study, StudyError


RAN_PAST = "ran to the end"


def _diag_outcome(job: Any, failed_at_s: float) -> Tuple[str, bool]:
    """A diagnosis rerun's outcome in words, and whether it ran past the failure."""
    state = state_name(job.state)
    t = float(getattr(job, "t_s", 0.0) or 0.0)
    if state == "succeeded":
        return RAN_PAST, True
    if state == "failed" and job.failure_kind in SIMULATION_FAILURES:
        when = "later" if t > failed_at_s + 1e-9 else "too"
        return f"failed {when}: {job.failure_kind} at {t:.0f} s", False
    if state == "failed":
        return f"did not run ({job.failure_kind})", False
    if state in ("queued", "running"):
        return f"{state} ({100 * float(job.progress):.0f} %)", False
    return state, False


def _diag_texts(jobs_by_name: Dict[str, Any], failed_at_s: float,
                carried_text: Any = "") -> Tuple[list, bool]:
    """A failed run's diagnoses as the report lists them, "NAME: outcome (job)" each, and whether
    one ran past the failure: each diagnosis's last rerun in this store, else what a carried row
    said of it (an earlier store's, where a rerun may not have ended)."""
    outcomes = diagnosis_entries(carried_text)
    for name, js in jobs_by_name.items():
        text, _ = _diag_outcome(js[-1], failed_at_s)
        outcomes[name] = f"{text} ({js[-1].id})"
    past = any(o.startswith(RAN_PAST) for o in outcomes.values())
    return [f"{name}: {o}" for name, o in outcomes.items()], past


def collect(study: Study, client: Any, out_dir: os.PathLike,
            carried: Optional[Carried] = None) -> Path:
    """Writes the study's data from the store into out_dir: runs.csv (one row per run: state,
    failure, outcome, seed, the swept keys, the run's settings, every result), samples.csv.gz
    (the sample columns the figures need) and msrd.csv.gz (each run's MSRD curve). A run with
    no live or ended job in the store takes its row, samples and curve from `carried` (an
    earlier store's data), if that holds it. Returns out_dir."""
    import pandas as pd
    out = folder(out_dir, "data folder")
    found, source, stale = _run_jobs(study, client)
    diag = _diag_of_runs(study, client, source)
    rows, samples, curves, named = [], [], [], []
    n_carried = 0
    for i, run in enumerate(study.runs()):
        row: Dict[str, Any] = {"run": i, **run.point, "seed": run.seed,
                               "settings": json.dumps(study.settings(run), sort_keys=True),
                               "base_sha256": _base_sha(study)}
        have = found.get(i, [])
        if _takes_carried(have, carried, i):
            old = carried.rows[i]
            row.update({k: v for k, v in old.items() if k not in row and k != "carried_from"})
            # The settings the run was made with, as it recorded them (the same run as today's
            # settings, which may spell it otherwise: an earlier version's keys, a default then
            # given explicitly).
            if isinstance(old.get("settings"), str) and old["settings"]:
                row["settings"] = old["settings"]
            row["carried_from"] = str(carried.source)
            # A diagnosis rerun of a carried failure in this store says how it went.
            if old.get("state") == "failed" and diag.get(i):
                texts, past = _diag_texts(diag[i], float(old.get("t_end_s") or 0.0),
                                          old.get("diagnoses"))
                row.update(diagnoses="; ".join(texts), diag_ran_past=past)
            jid = old["job_id"]
            samples += carried.samples[carried.samples["job_id"] == jid].to_dict("records")
            curves += carried.msrd[carried.msrd["job_id"] == jid].values.tolist()
            if carried.curves is not None:
                named += carried.curves[carried.curves["job_id"] == jid].values.tolist()
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
        row.update(job_id=j.id, state=state_name(j.state), failure_kind=j.failure_kind,
                   reason=j.reason, outcome=j.outcome, attempts=len(have), t_end_s=j.t_s)
        # A diagnosis that applies to the run's failure but would rerun the same numerics.
        noop = ([d.name for d in run_diagnoses(study, client, run)
                 if j.failure_kind in d.kinds and d.name not in diag.get(i, {})
                 and _diag_is_noop(study, client, run, d, j)]
                if row["state"] == "failed" and i not in source else [])
        if row["state"] == "failed" and (diag.get(i) or noop):
            # Each diagnosis's last rerun: "NAME: outcome (job)"; the failure is the point's
            # unless one ran past it.
            texts, past = _diag_texts(diag.get(i, {}), float(j.t_s or 0.0))
            texts += [f"{name}: {NOOP_TEXT}" for name in noop]
            row.update(diagnoses="; ".join(texts), diag_ran_past=past)
        if row["state"] in ("succeeded", "failed"):
            job = client.job(j.id)
            r = job.results_message(True)
            row.update({x.name: x.value for x in r.results})
            cols = list(r.columns)
            # A run that failed before its first step (its preparation) has no columns at all.
            lacking = [c for c in study.columns if c not in cols]
            if lacking and cols:
                raise StudyError(_lacks(study, run, j.id, "sample column", lacking))
            keep = [c for c in [*SAMPLE_COLUMNS, *study.columns] if c in cols]
            idx = [cols.index(c) for c in keep]
            for s in r.samples:
                samples.append({"job_id": j.id, "t_s": s.t_s,
                                **{c: s.values[k] for c, k in zip(keep, idx)}})
            have_curves = set()
            for c in getattr(r, "curves", []):
                have_curves.add(c.name)
                if c.name == "msrd":
                    curves += [[j.id, x, y] for x, y in zip(c.x, c.y)]
                elif c.name in study.curves:
                    named += [[j.id, c.name, x, y] for x, y in zip(c.x, c.y)]
            # A run ends with its curves; one that failed has none to lack.
            lacking = [c for c in study.curves if c not in have_curves]
            if lacking and row["state"] == "succeeded":
                raise StudyError(_lacks(study, run, j.id, "curve", lacking))
        rows.append(row)
    to_csv(pd.DataFrame(rows), out / "runs.csv", index=False)
    # gzip without a timestamp: the same data gives the same bytes (a report regenerated from
    # the store changes nothing in git unless the runs changed).
    gz = {"method": "gzip", "mtime": 0}
    to_csv(pd.DataFrame(samples, columns=["job_id", "t_s", *SAMPLE_COLUMNS, *study.columns]),
           out / "samples.csv.gz", index=False, compression=gz)
    to_csv(pd.DataFrame(curves, columns=["job_id", "lag_s", "msrd_um2"]),
           out / "msrd.csv.gz", index=False, compression=gz)
    if study.curves:
        to_csv(pd.DataFrame(named, columns=["job_id", "curve", "x", "y"]),
               out / "curves.csv.gz", index=False, compression=gz)
    meta = {"study": study.name, "file": str(study.path), "tag": study.tag,
            "collected_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "runs": len(rows), "stale_jobs": [j.id for j in stale],
            "shared_runs": {str(i): src for i, src in source.items()},
            "carried_runs": n_carried}
    write_text(out / "collected.json", json.dumps(meta, indent=1) + "\n")
    return out


def _lacks(study: Study, run: Any, job_id: str, what: str, names: Any) -> str:
    return (f"study.{what.split()[-1]}s: run {run.point} seed {run.seed} ({job_id}) has no "
            f"{what} {', '.join(names)}: its spec does not ask for the probe that writes it "
            "(an [observe] key in [spec]; `foam-run --keys` lists them)")


@dataclass
class Data:
    runs: Any       # DataFrame, one row per run, with the derived metrics of METRICS
    samples: Any    # DataFrame job_id, t_s, sample columns (and the study's `columns`)
    msrd: Any       # DataFrame job_id, lag_s, msrd_um2
    curves: Any = None  # DataFrame job_id, curve, x, y: the study's `curves`, where it names any


def load_data(study: Study, data_dir: os.PathLike) -> Data:
    import pandas as pd
    d = Path(data_dir)
    for f in ("runs.csv", "samples.csv.gz", "msrd.csv.gz"):
        if not (d / f).is_file():
            raise StudyError(f"data: {d / f} is missing (collect it with `report` against foamd)")
    runs = pd.read_csv(d / "runs.csv")
    samples = pd.read_csv(d / "samples.csv.gz")
    msrd = pd.read_csv(d / "msrd.csv.gz")
    curves = pd.read_csv(d / "curves.csv.gz") if (d / "curves.csv.gz").is_file() else None
    runs = derive_metrics(study, runs, samples, msrd)
    return Data(runs, samples, msrd, curves)


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


def _ran_past(runs: Any) -> Any:
    """Per run: whether a diagnosis rerun of it ran past its failure (False without the column:
    data collected before diagnoses)."""
    import pandas as pd
    if "diag_ran_past" not in runs:
        return pd.Series(False, index=runs.index)
    return runs["diag_ran_past"].map(lambda v: v is True or str(v).lower() == "true")


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
