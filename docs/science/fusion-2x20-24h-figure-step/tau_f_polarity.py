#!/usr/bin/python3
"""Does keeping the prepared polarities (scene.polarity_from_preparation) speed the base point's
fusion? The figure studies' base point (fig8-reduced's p_a r/2γ = 0.33, α = 0.4375, and
fig9-reduced's τ_p = 10 min: the same runs) keeps each cell's polarity from its spheroid's
preparation; step fitness's runs of the same point at the same step drew fresh polarities. The
two ran for different lengths (6 h, 4 h), and Eq. 1's τ_f depends on the window it is fitted
over, so every run is refitted here over the same first WINDOW hours (scipy's least squares on
the committed θ(t) samples; over a run's whole length it gives the engine's τ_f to the printed
digit, which the table shows for step fitness's runs).

    docs/science/fusion-2x20-24h-figure-step/tau_f_polarity.py [--data docs/science] [--window-h 4] [--step 1.0]

Prints a markdown table per run, then for τ_f and θ at 0.5 h and 1 h the difference of medians
(prepared − fresh) with its bootstrap 95 % interval (activefoam.trends) and the exact
Mann–Whitney two-sided p. Needs the Python client on PYTHONPATH (build/release/python).
"""
import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import curve_fit
from scipy.stats import mannwhitneyu

from activefoam import trends


def eq1(t, theta_eq, theta0, tau_f):
    return theta_eq + (theta0 - theta_eq) * np.exp(-t / tau_f)


def fit_tau_f(g: pd.DataFrame, window_s: float) -> float:
    g = g[(g.t_s <= window_s + 1e-9) & np.isfinite(g.theta_deg)]
    p, _ = curve_fit(eq1, g.t_s.values, g.theta_deg.values, p0=[90.0, 30.0, 2000.0],
                     maxfev=20000)
    return float(p[2])


def theta_at(g: pd.DataFrame, t: float) -> float:
    g = g[np.isfinite(g.theta_deg)]
    i = int(np.argmin(np.abs(g.t_s.values - t)))
    return float(g.theta_deg.values[i]) if abs(g.t_s.values[i] - t) <= 60 else float("nan")


def load(root: Path, study: str):
    runs = pd.read_csv(root / study / "data" / "runs.csv")
    samples = pd.read_csv(root / study / "data" / "samples.csv.gz")
    return runs, samples


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="docs/science")
    ap.add_argument("--window-h", type=float, default=4.0)
    ap.add_argument("--step", type=float, default=1.0, help="step fitness's Δt to compare with")
    a = ap.parse_args()
    root, window = Path(a.data), a.window_h * 3600
    rows = []

    runs, samples = load(root, "step-fitness")
    settings = runs.settings.map(json.loads)
    dt = settings.map(lambda s: s.get("numerics.dt_s"))
    # Step fitness ran two arms at Δt 0.5 s (the law, the overlap within prisms): one at a time.
    arms = {json.dumps({k: v for k, v in s.items() if k.startswith("numerics.")}, sort_keys=True)
            for s in settings[dt == a.step]}
    if len(arms) != 1:
        print(f"tau_f_polarity: step fitness has {len(arms)} arms at Δt {a.step:g} s "
              f"({'; '.join(sorted(arms)) or 'none'}); choose a step with one", file=sys.stderr)
        return 2
    for _, r in runs[(dt == a.step) & (runs.state == "succeeded")].iterrows():
        g = samples[samples.job_id == r.job_id]
        if g.t_s.max() < window - 60:
            continue
        rows.append(dict(polarity="fresh", study="step-fitness", seed=int(r.seed),
                         job=r.job_id, engine_tau_f=r.tau_f_s, t_end_h=g.t_s.max() / 3600,
                         tau_f=fit_tau_f(g, window), th05=theta_at(g, 1800),
                         th1=theta_at(g, 3600)))

    seen = set()
    for study, point in (("fig8-reduced", {"cells.pa_reduced": 0.33, "cells.alpha": 0.4375}),
                         ("fig9-reduced", {"cells.tau_p_s": 600, "cells.alpha": 0.4375})):
        runs, samples = load(root, study)
        sel = runs.state == "succeeded"
        for k, v in point.items():
            sel &= np.isclose(runs[k].astype(float), v)
        for _, r in runs[sel].iterrows():
            if r.job_id in seen:
                continue  # a shared run: fig9's τ_p = 10 min takes fig8's base point's jobs
            seen.add(r.job_id)
            g = samples[samples.job_id == r.job_id]
            rows.append(dict(polarity="prepared", study=study, seed=int(r.seed), job=r.job_id,
                             engine_tau_f=r.tau_f_s, t_end_h=g.t_s.max() / 3600,
                             tau_f=fit_tau_f(g, window), th05=theta_at(g, 1800),
                             th1=theta_at(g, 3600)))

    t = pd.DataFrame(rows)
    print(f"Eq. 1 refitted over the first {a.window_h:g} h; step fitness at Δt {a.step:g} s.\n")
    print("| polarity | study | seed | job | run (h) | engine τ_f (s, whole run) | "
          f"τ_f over {a.window_h:g} h (s) | θ at 0.5 h (°) | θ at 1 h (°) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for _, r in t.sort_values(["polarity", "seed"]).iterrows():
        print(f"| {r.polarity} | {r.study} | {r.seed} | {r.job} | {r.t_end_h:.1f} | "
              f"{r.engine_tau_f:.0f} | {r.tau_f:.0f} | {r.th05:.1f} | {r.th1:.1f} |")
    fresh, prep = t[t.polarity == "fresh"], t[t.polarity == "prepared"]
    print(f"\nprepared − fresh (medians; {len(prep)} against {len(fresh)} runs):\n")
    print("| metric | fresh median [min, max] | prepared median [min, max] | difference [95 %] "
          "| Mann–Whitney p |")
    print("|---|---|---|---|---|")
    for col, name in (("tau_f", f"τ_f over {a.window_h:g} h (s)"), ("th05", "θ at 0.5 h (°)"),
                      ("th1", "θ at 1 h (°)")):
        f, p = fresh[col].dropna().values, prep[col].dropna().values
        if len(f) == 0 or len(p) == 0:
            continue
        d = trends.diff_of_medians(f, p)
        mw = mannwhitneyu(p, f, alternative="two-sided", method="exact").pvalue
        print(f"| {name} | {np.median(f):.4g} [{f.min():.4g}, {f.max():.4g}] | "
              f"{np.median(p):.4g} [{p.min():.4g}, {p.max():.4g}] | "
              f"{d.diff:.3g} [{d.lo:.3g}, {d.hi:.3g}] | {mw:.3g} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
