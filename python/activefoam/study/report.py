"""A study's report: its figures (θ(t) and MSRD curves; the metrics against the swept key) and
tables, rendered from its data with matplotlib.
"""

from __future__ import annotations

import os
import textwrap
from pathlib import Path
from typing import Any, List

from activefoam.study.data import Data, _msrd_series, _series, study_radius
from activefoam.study.fitness import render_fitness
from activefoam.study.outputs import folder, savefig, to_csv, write_text
from activefoam.study.studyfile import METRICS, Study, _same
from activefoam.study.tables import (failed_runs_markdown, summary_markdown, summary_table,
                                     unsaturated_fits_markdown)


def _value(v: Any) -> str:
    """A key's value in a figure's labels: 0.037162162162162164 crowds a panel's title."""
    return format(v, ".4g") if isinstance(v, float) else str(v)


def _label(study: Study, key: str) -> str:
    if key == study.x and study.x_label:
        return study.x_label
    if key == study.by and study.by_label:
        return study.by_label
    return key


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
    out = folder(out_dir)
    written: List[Path] = []
    runs = data.runs
    table = summary_table(study, runs)
    to_csv(table, out / "summary.csv", index=False)
    extra = [m for m in (failed_runs_markdown(study, runs),
                         unsaturated_fits_markdown(study, runs)) if m]
    write_text(out / "summary.md", summary_markdown(study, table)
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
    savefig(fig, out / f"{study.name}-curves.png", dpi=110)
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
    savefig(fig, out / f"{study.name}-trends.png", dpi=110)
    plt.close(fig)
    written.append(out / f"{study.name}-trends.png")

    if study.fitness:
        written += render_fitness(study, data, out)
    return written
