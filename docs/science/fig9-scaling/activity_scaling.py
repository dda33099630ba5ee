#!/usr/bin/python3
"""Fig. S13 in ours: do the reduced studies' runs follow the supplement's activity scaling?

The supplement reads its cells' rearrangements (normalised unique contacts Y) as one function of
a dimensionless activity A_π = (p_a r/γ) α^a1 (τ_p/τ_γ)^a2 N^a3, with theoretical exponents
a1 = −1/2, a2 = 1/4, a3 ≈ 0 (Supp. Fig. 13). A free persistent walker would have a2 = 1/2 (its
speed goes with p_a, its diffusivity with v² τ_p). This reads every succeeded run of the given
studies' committed data (runs.csv, written by `scripts/study.sh … --report`), resolves each run's
reduced parameters from its settings (defaults: the base point), takes off the passive baseline
Y₀(α) (the median of the p_a = 0 runs at that α) and fits

    log(Y − Y₀) = c + k log(p_a r/γ) + b1 log α + b2 log(τ_p/τ_γ) + b3 log N

by least squares over runs, so that a_i = b_i / k; intervals are 95 % bootstrap over runs
resampled within each point. --no-baseline fits Y itself (Y₀ = 0: the mixing time, which
falls with activity, so k < 0). A key that has one value across the runs is left out of the fit
(its exponent reads "—").

    docs/science/fig9-scaling/activity_scaling.py DATA_DIR [DATA_DIR…] [--metric unique_contacts_norm]
        [--duration 21600] [--plot FILE.png] [--boot 2000] [--also mixing_time_s,…]
        [--no-baseline]

Runs enter only at the base of everything A_π does not name (L_η/r 0.5; the keys of
`ALLOWED` may differ) and at one duration (Y grows with time). A run whose Y − Y₀ ≤ 0, or whose
α has no p_a = 0 runs, is named and left out. Prints the points (their parameters, A_π with the
supplement's exponents, median Y, and the medians of the runs.csv columns named by --also) and
the fit as markdown.
"""
import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

R_UM = 8.88  # mean cell radius of the reduced parameters (docs/model.md §9.2), unless a run sets it
GAMMA_REF = 0.5  # nN/µm
BASE = {"alpha": 0.4375, "tau_p_s": 600.0, "tau_gamma_s": 10.0, "n_cells": 20.0,
        "l_eta_reduced": 0.5}
# The keys a run may set and still enter: A_π's own parameters, the numerics, the run's
# bookkeeping, and the two that Fig. 10's τ_γ points scale with η/γ (the shell's times). Any
# other key changes something A_π does not name, and the run is left out (named).
ALLOWED_PREFIXES = ("numerics.",)
ALLOWED = {"seed", "duration_s", "scene.polarity_from_preparation", "cells.tau_k_s",
           "cells.gamma", "cells.p_a", "cells.pa_reduced", "cells.alpha", "cells.tau_p_s",
           "cells.tau_gamma_s", "scene.n_cells", "cells.l_eta_reduced", "cells.radius_mean_um"}


class Skip(Exception):
    pass


def parameters(settings):
    """The run's (p_a r/γ, α, τ_p, τ_γ, N) from its settings, base values where unset."""
    for k in settings:
        if k not in ALLOWED and not k.startswith(ALLOWED_PREFIXES):
            raise Skip(f"sets {k}")
    if float(settings.get("cells.l_eta_reduced", BASE["l_eta_reduced"])) != BASE["l_eta_reduced"]:
        raise Skip("L_η/r is not the base's (A_π has no friction)")
    gamma = float(settings.get("cells.gamma", GAMMA_REF))
    if "cells.pa_reduced" in settings:
        if "cells.gamma" in settings:
            raise Skip("sets both cells.pa_reduced and cells.gamma")
        pa_r_over_gamma = 2.0 * float(settings["cells.pa_reduced"])
    elif "cells.p_a" in settings:
        radius = float(settings.get("cells.radius_mean_um", R_UM))
        pa_r_over_gamma = float(settings["cells.p_a"]) * radius / gamma
    else:
        raise Skip("sets neither cells.pa_reduced nor cells.p_a")
    tau_gamma = float(settings.get("cells.tau_gamma_s", BASE["tau_gamma_s"] * GAMMA_REF / gamma))
    return {"pa_r_over_gamma": pa_r_over_gamma,
            "alpha": float(settings.get("cells.alpha", BASE["alpha"])),
            "tau_p_s": float(settings.get("cells.tau_p_s", BASE["tau_p_s"])),
            "tau_gamma_s": tau_gamma,
            "n_cells": float(settings.get("scene.n_cells", BASE["n_cells"]))}


def a_pi(p, a1=-0.5, a2=0.25, a3=0.0):
    return (p["pa_r_over_gamma"] * p["alpha"] ** a1 * (p["tau_p_s"] / p["tau_gamma_s"]) ** a2
            * p["n_cells"] ** a3)


def load(dirs, metric, duration, also=(), max_pa=None):
    """Succeeded runs (one row per job) with their parameters; and what was left out, why.
    max_pa: the largest p_a r/2γ (at the run's own γ) kept — beyond it a 2 × 20 doublet stops
    holding together (fig10's p_a r/2γ = 2) and its contacts saturate, a curve no power law fits."""
    rows, skipped, seen = [], [], set()
    for d in dirs:
        runs = pd.read_csv(Path(d) / "runs.csv")
        for _, r in runs.iterrows():
            job = r.get("job_id")
            if r.get("state") != "succeeded" or job in seen or pd.isna(r.get(metric)):
                continue
            seen.add(job)
            settings = json.loads(r["settings"])
            where = f"{Path(d).parent.name} {job}"
            if float(settings.get("duration_s", duration)) != duration:
                skipped.append((where, f"duration {settings.get('duration_s')} s"))
                continue
            try:
                p = parameters(settings)
            except Skip as e:
                skipped.append((where, str(e)))
                continue
            if max_pa is not None and p["pa_r_over_gamma"] / 2 > max_pa:
                skipped.append((where, f"p_a r/2γ {p['pa_r_over_gamma'] / 2:.4g} > --max-pa "
                                       f"{max_pa:g}"))
                continue
            rows.append({**p, **{c: float(r.get(c, math.nan)) for c in also},
                         "y": float(r[metric]), "job_id": job,
                         "study": Path(d).parent.name, "seed": int(r["seed"])})
    return pd.DataFrame(rows), skipped


KEYS = ["pa_r_over_gamma", "alpha", "tau_p_s", "tau_gamma_s", "n_cells"]


def with_baseline(df, baseline=True):
    """Y − Y₀(α), Y₀ the median of the p_a = 0 runs at that α (0 without the baseline: Y itself,
    for a metric such as the mixing time that has no passive part to take off); rows that
    cannot be used named."""
    base = df[df.pa_r_over_gamma == 0].groupby("alpha").y.median()
    act = df[df.pa_r_over_gamma > 0].copy()
    act["y0"] = act.alpha.map(base) if baseline else 0.0
    named = []
    for _, r in act[act.y0.isna()].iterrows():
        named.append((f"{r.study} {r.job_id}", f"no p_a = 0 runs at α {r.alpha}"))
    act = act[act.y0.notna()]
    act["dy"] = act.y - act.y0
    for _, r in act[act.dy <= 0].iterrows():
        named.append((f"{r.study} {r.job_id}", f"Y − Y₀ = {r.dy:.3g} ≤ 0"))
    return act[act.dy > 0].reset_index(drop=True), base, named


def design(act):
    """Columns of the fit: log p_a r/γ first, then the other keys that vary."""
    cols = ["pa_r_over_gamma"]
    for k in ["alpha", "n_cells"]:
        if act[k].nunique() > 1:
            cols.append(k)
    ratio = act.tau_p_s / act.tau_gamma_s
    X = [np.ones(len(act))] + [np.log(act[c].to_numpy()) for c in cols]
    names = ["c"] + cols
    if ratio.nunique() > 1:
        X.insert(2, np.log(ratio.to_numpy()))
        names.insert(2, "tau_ratio")
    return np.column_stack(X), names


def fit(act):
    """Exponents relative to p_a's: {'k', 'a1', 'a2', 'a3'} (NaN where the key does not vary)."""
    X, names = design(act)
    if len(act) <= X.shape[1]:
        raise ValueError(f"{len(act)} runs for {X.shape[1]} coefficients")
    beta, *_ = np.linalg.lstsq(X, np.log(act.dy.to_numpy()), rcond=None)
    b = dict(zip(names, beta))
    k = b["pa_r_over_gamma"]
    return {"k": k, "a1": b.get("alpha", math.nan) / k, "a2": b.get("tau_ratio", math.nan) / k,
            "a3": b.get("n_cells", math.nan) / k}


def bootstrap(act, n, seed=1):
    rng = np.random.default_rng(seed)
    groups = [g.index.to_numpy() for _, g in act.groupby(KEYS)]
    out = []
    for _ in range(n):
        idx = np.concatenate([rng.choice(g, size=len(g), replace=True) for g in groups])
        try:
            out.append(fit(act.loc[idx]))
        except (ValueError, np.linalg.LinAlgError):
            continue
    return pd.DataFrame(out)


def fmt(x, digits=3):
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}g}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dirs", nargs="+", help="studies' data folders (runs.csv)")
    ap.add_argument("--metric", default="unique_contacts_norm")
    ap.add_argument("--duration", type=float, default=21600.0)
    ap.add_argument("--boot", type=int, default=2000)
    ap.add_argument("--no-baseline", action="store_true",
                    help="fit Y itself (a metric with no passive part, e.g. mixing_time_s)")
    ap.add_argument("--also", default="",
                    help="runs.csv columns whose point medians the table shows too (comma-separated)")
    ap.add_argument("--max-pa", type=float,
                    help="leave out runs whose p_a r/2γ (at their own γ) is above this")
    ap.add_argument("--plot", help="a PNG: Y − Y₀ against A_π, the supplement's and the fit's")
    a = ap.parse_args(argv)
    for d in a.dirs:
        if not (Path(d) / "runs.csv").is_file():
            print(f"error: {d}: no runs.csv", file=sys.stderr)
            return 2
    also = [c for c in a.also.split(",") if c]
    for d in a.dirs:
        header = pd.read_csv(Path(d) / "runs.csv", nrows=0).columns
        for c in [a.metric] + also:
            if c not in header:
                print(f"error: {d}/runs.csv has no column {c!r}", file=sys.stderr)
                return 2
    df, skipped = load(a.dirs, a.metric, a.duration, also, a.max_pa)
    if df.empty:
        print("error: no succeeded run at the base of what A_π leaves out", file=sys.stderr)
        return 2
    act, base, named = with_baseline(df, not a.no_baseline)
    skipped += named
    what = "Y" if a.no_baseline else "Y − Y₀(α)"
    print(f"# {a.metric}: {what} against A_π, {len(act)} runs at {act.groupby(KEYS).ngroups} "
          f"points ({', '.join(sorted(set(act.study)))})\n")
    if not a.no_baseline:
        print("Y₀(α), the p_a = 0 median: " +
              ", ".join(f"α {al}: {y:.3g}" for al, y in base.items()) + "\n")
    print("| p_a r/2γ | α | τ_p (s) | τ_γ (s) | N | runs | A_π (supplement) | median Y | "
          "median Y − Y₀ | " + "".join(f"median {c} | " for c in also) + "studies |")
    print("|---|---|---|---|---|---|---|---|---|" + "---|" * len(also) + "---|")
    pts = act.groupby(KEYS)
    for key, g in sorted(pts, key=lambda kv: a_pi(dict(zip(KEYS, kv[0])))):
        p = dict(zip(KEYS, key))
        print(f"| {p['pa_r_over_gamma'] / 2:.4g} | {p['alpha']:g} | {p['tau_p_s']:g} | "
              f"{p['tau_gamma_s']:g} | {p['n_cells']:g} | {len(g)} | {a_pi(p):.3g} | "
              f"{g.y.median():.3g} | {g.dy.median():.3g} | " +
              "".join(f"{g[c].median():.4g} | " for c in also) +
              f"{', '.join(sorted(set(g.study)))} |")
    est = fit(act)
    boot = bootstrap(act, a.boot) if a.boot > 0 else pd.DataFrame()
    print("\n| exponent | the supplement's (theory) | a free walker's | ours | 95 % interval |")
    print("|---|---|---|---|---|")
    theory = {"k": ("—", "—"), "a1": ("−1/2", "—"), "a2": ("1/4", "1/2"), "a3": ("≈ 0", "—")}
    label = {"k": f"k (log {what} per log p_a r/γ)", "a1": "a1 (α)", "a2": "a2 (τ_p/τ_γ)",
             "a3": "a3 (N)"}
    for name in ["k", "a1", "a2", "a3"]:
        lo = hi = math.nan
        if name in boot and boot[name].notna().any():
            lo, hi = np.nanpercentile(boot[name], [2.5, 97.5])
        print(f"| {label[name]} | {theory[name][0]} | {theory[name][1]} | {fmt(est[name])} | "
              f"[{fmt(lo)}, {fmt(hi)}] |")
    if skipped:
        groups = {}
        for where, why in skipped:
            study, job = where.split(" ", 1)
            groups.setdefault((study, why), []).append(job)
        print("\nLeft out: " + "; ".join(
            f"{study}, {len(jobs)} run{'s' if len(jobs) > 1 else ''} ({why}"
            + (f": {', '.join(jobs)})" if len(jobs) <= 3 else ")")
            for (study, why), jobs in sorted(groups.items())))
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import matplotlib.ticker
        fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
        ours = {"a1": 0 if math.isnan(est["a1"]) else est["a1"],
                "a2": 0 if math.isnan(est["a2"]) else est["a2"],
                "a3": 0 if math.isnan(est["a3"]) else est["a3"]}
        for ax, ex, title in [(axes[0], {}, "A_π, the supplement's exponents"),
                              (axes[1], ours, "A_π, the exponents fitted to ours")]:
            for study, g in act.groupby("study"):
                x = [a_pi(r, **ex) for _, r in g.iterrows()]
                ax.scatter(x, g.dy, label=study, s=18)
            ax.set_xscale("log")
            ax.set_yscale("log")
            for axis in (ax.xaxis, ax.yaxis):
                axis.set_major_locator(matplotlib.ticker.LogLocator(subs=(1, 1.5, 2, 3, 5, 7)))
                axis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
                axis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_xlabel(title)
            ax.axvline(a_pi({"pa_r_over_gamma": 0.66, "alpha": 0.4375, "tau_p_s": 150,
                             "tau_gamma_s": 10, "n_cells": 20}, **ex), color="k", ls=":", lw=1)
            ax.grid(True, which="both", alpha=0.3)
        axes[0].set_ylabel(f"{a.metric} − Y₀(α)")
        axes[1].legend(fontsize=7)
        fig.suptitle("dotted: Fig. 9's τ_p = 2.5 min at the base point, where the supplement's "
                     "tissue jams", fontsize=9)
        fig.tight_layout()
        fig.savefig(a.plot, dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main())
