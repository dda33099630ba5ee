"""A study's report tables: per grid point the runs, failures and each metric's median and IQR
over seeds (summary.csv, summary.md), and the lists of failed runs and of Eq. 1 fits longer
than their run.
"""

from __future__ import annotations

import math
from typing import Any, Dict, List, Sequence

from activefoam import trends
from activefoam.study.data import _ran_past
from activefoam.study.studyfile import METRICS, Study, _same, shown_metrics


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
    diagnoses = study.listed_diagnoses()
    if diagnoses:
        how = ("a diagnosis reruns the run with some keys changed (the study's diagnoses: "
               + "; ".join(f"{d.name} sets " + ", ".join(
                   f"{k} = {_toml(v)}" for k, v in d.spec.items())
                   + (f" ({d.title})" if d.title else "") + " for " + ", ".join(d.kinds)
                   for d in diagnoses)
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
