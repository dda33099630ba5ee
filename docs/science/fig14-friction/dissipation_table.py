#!/usr/bin/python3
"""Tables of bench/study_dissipation's output: per configuration, the median share of the power
each term dissipates (its samples' medians: a contact snapping now and then spikes the springs'
implicit part a hundredfold for one sample), the same at the cells' scale (their affine motion),
the centroid speeds and the MSRD at a few lags with the time it first reaches r².

    docs/science/fig14-friction/dissipation_table.py OUT.csv [OUT2.csv …] [--radius-um 8.88] [--lags 600,1800,3600]

Prints Markdown. The power balance (the terms' sum against vᵀF, the forces' power) is checked
per sample and its worst relative error printed: it says Γ was rebuilt as the step used it.
"""
import argparse
import sys

import numpy as np
import pandas as pd

TERMS = ["p_medium", "p_cortex", "p_friction_t", "p_friction_n", "p_spring_implicit"]
AFFINE = ["p_medium_affine", "p_cortex_affine", "p_friction_t_affine", "p_friction_n_affine"]


def crossing(t, y, level):
    """First time y reaches level, linear between samples; NaN if never."""
    above = np.nonzero(y >= level)[0]
    if not len(above):
        return float("nan")
    k = above[0]
    if k == 0:
        return float(t[0])
    return float(t[k - 1] + (level - y[k - 1]) * (t[k] - t[k - 1]) / (y[k] - y[k - 1]))


def table(frames, radius, lags):
    d = pd.concat(frames, ignore_index=True)
    key = "config" if "config" in d.columns else "l_eta_reduced"
    total = d[TERMS].sum(axis=1)
    balance = float(((total - d["p_forces"]).abs() / d["p_forces"].abs()).max())
    rows = []
    for name, g in d.groupby(key, sort=False):
        g = g.sort_values("t_s")
        s = g[TERMS].div(g[TERMS].sum(axis=1), axis=0).median()
        a = g[AFFINE].div(g[AFFINE].sum(axis=1), axis=0).median()
        vs = (g["p_cortex_vertex_scale"] / g["p_cortex"]).median()
        row = {"config": name, "ξ (kPa·s/µm)": f"{g['xi'].iloc[0]:.4g}"}
        for t, label in zip(TERMS, ["medium", "cortex", "friction ∥", "friction ⊥",
                                    "springs (implicit)"]):
            row[f"{label} %"] = f"{100 * s[t]:.0f}"
        row["cortex at vertex scale %"] = f"{100 * vs:.0f}"
        for t, label in zip(AFFINE, ["medium", "cortex", "friction ∥", "friction ⊥"]):
            row[f"cell scale: {label} %"] = f"{100 * a[t]:.0f}"
        row["v rel. (µm/min)"] = f"{g['v_relative_um_min'].median():.2f}"
        t, m = g["t_s"].to_numpy(), g["msrd_um2"].to_numpy() / radius**2
        for lag in lags:
            row[f"MSRD({lag:g} s)/r²"] = (f"{np.interp(lag, t, m):.2f}" if t[-1] >= lag - 1e-9
                                          else "—")
        c = crossing(t, m, 1.0)
        row["MSRD = r² at (s)"] = "—" if np.isnan(c) else f"{c:.0f}"
        rows.append(row)
    out = pd.DataFrame(rows)
    lines = ["| " + " | ".join(out.columns) + " |", "|" + "---|" * len(out.columns)]
    lines += ["| " + " | ".join(str(v) for v in r) + " |" for r in out.itertuples(index=False)]
    return "\n".join(lines), balance


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("csv", nargs="+")
    ap.add_argument("--radius-um", type=float, default=8.88)
    ap.add_argument("--lags", default="600,1800,3600")
    a = ap.parse_args(argv)
    frames = [pd.read_csv(f) for f in a.csv]
    text, balance = table(frames, a.radius_um, [float(x) for x in a.lags.split(",")])
    print(text)
    print(f"\nPower balance: the terms' sum is vᵀF within {100 * balance:.2g} % at every sample.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
