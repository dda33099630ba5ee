#!/usr/bin/python3
"""bench/study_shape's runs as tables: where the shape index's rise with friction comes from.

    bench/shape_table.py RUN.csv... [--windows 0:300,3000:3600,6600:7200]
                         [--low 0.25] [--high 2] [--pair "LABEL_A|LABEL_B" ...]

Each RUN.csv is one study_shape invocation (one prepared aggregate; the file name's "seedN"
names the seed), with its per-cell file beside it (RUN-cells.csv from STUDY_SHAPE_CELLS, or
RUN-cells.csv.gz).
Prints, per window (mean over the window's samples):
  1. each run's shape index q, its vertex-scale smoothed value, their difference (the ripples'
     share), the cells' elongation, the contact fraction and θ;
  2. the differences --low − --high (and each --pair A − B) of the same quantities, paired by
     seed and preparation (same aggregate, same noise), with their median over seeds; and the
     prepared aggregates themselves (t = 0);
  3. q against how buried the cells are: the mean q of the cells whose contact fraction is in
     each third of the pooled range, per configuration; and, in the paired differences, the
     part of Δq that the change of contact fraction accounts for (the cells' q regressed on
     their contact fraction, pooled over the pair's two runs in the window: slope × Δf).
"""
import argparse
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd


def load(paths):
    runs, cells = [], []
    for p in paths:
        p = Path(p)
        m = re.search(r"seed(\d+)", p.name)
        seed = int(m.group(1)) if m else 0
        d = pd.read_csv(p, dtype={"config": str})
        d["seed"] = seed
        runs.append(d)
        c = p.with_name(p.stem + "-cells.csv")
        if not c.exists():
            c = p.with_name(p.stem + "-cells.csv.gz")  # as committed
        if c.exists():
            cd = pd.read_csv(c, dtype={"config": str})
            cd["seed"] = seed
            cd["prep_l_eta_reduced"] = d["prep_l_eta_reduced"].iloc[0]
            cells.append(cd)
    runs = pd.concat(runs, ignore_index=True)
    cells = pd.concat(cells, ignore_index=True) if cells else None
    return runs, cells


def window_means(runs, lo, hi):
    w = runs[(runs.t_s >= lo) & (runs.t_s <= hi)].copy()
    w["ripple"] = w.q - w.q_smooth
    cols = ["q", "q_smooth", "ripple", "elong", "contact_fraction", "theta_deg"]
    return w.groupby(["seed", "prep_l_eta_reduced", "config"])[cols].mean().reset_index()


def slope(cells, seed, prep, configs, lo, hi):
    """q against the contact fraction over the cells of these runs in the window."""
    if cells is None:
        return np.nan
    c = cells[(cells.seed == seed) & (cells.prep_l_eta_reduced == prep) &
              cells.config.isin(configs) & (cells.t_s >= lo) & (cells.t_s <= hi)]
    if len(c) < 3:
        return np.nan
    return np.polyfit(c.contact_fraction, c.q, 1)[0]


def paired_differences(m, cells, pairs, lo, hi):
    """(seed, prep, name, difference of the window means, dq/df) for each pair (A, B) of
    configurations run from the same aggregate: A − B."""
    rows = []
    for (seed, prep), g in m.groupby(["seed", "prep_l_eta_reduced"]):
        g = g.set_index("config")
        for lo_c, hi_c in pairs:
            if lo_c in g.index and hi_c in g.index:
                d = g.loc[lo_c] - g.loc[hi_c]
                k = slope(cells, seed, prep, [lo_c, hi_c], lo, hi)
                rows.append((seed, prep, f"{lo_c} − {hi_c}", d, k))
    return rows


def summarize(rows):
    """Per difference and preparation run at more than one seed: Δq and its contact part
    (dq/df × Δf), each as median (min to max); absolute, since Δq may be near 0."""
    out = []
    keys = sorted({(prep, name) for _, prep, name, _, _ in rows})
    for prep, name in keys:
        sel = [(d, k) for _, p, n, d, k in rows if p == prep and n == name]
        if len(sel) < 2:
            continue
        dq = np.array([d.q for d, _ in sel])
        if np.all(dq == 0):
            continue  # t = 0: the same aggregate
        part = np.array([k * d.contact_fraction for d, k in sel])
        out.append(f"{name} (prepared at {prep:g}, {len(sel)} seeds): Δq {np.median(dq):+.4f} "
                   f"({dq.min():+.4f} to {dq.max():+.4f}), its contact part "
                   f"{np.nanmedian(part):+.4f} ({np.nanmin(part):+.4f} to {np.nanmax(part):+.4f})")
    return out


def fmt(x, digits=4):
    return "—" if pd.isna(x) else f"{x:.{digits}f}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--windows", default="0:300,3000:3600,6600:7200")
    ap.add_argument("--low", default="0.25", help="the high-friction configuration's label")
    ap.add_argument("--high", default="2", help="the low-friction configuration's label")
    ap.add_argument("--pair", action="append", default=[],
                    help="another paired difference, LABEL_A|LABEL_B (A − B)")
    a = ap.parse_args(argv)
    runs, cells = load(a.runs)
    windows = [tuple(float(v) for v in w.split(":")) for w in a.windows.split(",")]
    for lo, hi in windows:
        m = window_means(runs, lo, hi)
        print(f"\n### {lo:g}–{hi:g} s\n")
        print("| seed | prepared at L_η/r | run | q | q smoothed | q − smoothed | elongation "
              "| contact fraction | θ (°) |")
        print("|---|---|---|---|---|---|---|---|---|")
        for _, r in m.sort_values(["seed", "prep_l_eta_reduced", "config"]).iterrows():
            print(f"| {r.seed} | {r.prep_l_eta_reduced:g} | {r.config} | {fmt(r.q)} | "
                  f"{fmt(r.q_smooth)} | {fmt(r.ripple)} | {fmt(r.elong)} | "
                  f"{fmt(r.contact_fraction, 3)} | {fmt(r.theta_deg, 1)} |")
        rows = paired_differences(m, cells, [(a.low, a.high)] +
                                  [tuple(p.split("|")) for p in a.pair], lo, hi)
        if rows:
            print(f"\nPaired differences (same aggregate and noise), {lo:g}–{hi:g} s:\n")
            print("| seed | prepared at | difference | Δq | Δq smoothed | Δ(q − smoothed) "
                  "| Δelongation | Δcontact fraction f | dq/df (cells) | dq/df × Δf |")
            print("|---|---|---|---|---|---|---|---|---|---|")
            for seed, prep, name, d, k in rows:
                print(f"| {seed} | {prep:g} | {name} | {d.q:+.4f} | {d.q_smooth:+.4f} | "
                      f"{d.ripple:+.4f} | {d.elong:+.4f} | {d.contact_fraction:+.4f} | "
                      f"{fmt(k, 3)} | {k * d.contact_fraction:+.4f} |")
            across = summarize(rows)
            if across:
                print("\nAcross seeds (median, min–max): " + "; ".join(across))
    # The preparation's own effect: t = 0 of the runs, by the L_η/r it was prepared at.
    t0 = runs[runs.t_s == 0].groupby(["seed", "prep_l_eta_reduced"])[
        ["q", "q_smooth", "elong", "contact_fraction"]].first().reset_index()
    print("\n### The prepared aggregates (t = 0)\n")
    print("| seed | prepared at L_η/r | q | q smoothed | elongation | contact fraction |")
    print("|---|---|---|---|---|---|")
    for _, r in t0.sort_values(["seed", "prep_l_eta_reduced"]).iterrows():
        print(f"| {int(r.seed)} | {r.prep_l_eta_reduced:g} | {fmt(r.q)} | {fmt(r.q_smooth)} | "
              f"{fmt(r.elong)} | {fmt(r.contact_fraction, 3)} |")
    if cells is not None:
        lo, hi = windows[-1]
        c = cells[(cells.t_s >= lo) & (cells.t_s <= hi)].copy()
        edges = np.quantile(c.contact_fraction, [0, 1 / 3, 2 / 3, 1])
        c["third"] = np.clip(np.searchsorted(edges, c.contact_fraction, side="right") - 1, 0, 2)
        t = c.groupby(["prep_l_eta_reduced", "config", "third"]).q.mean().unstack()
        print(f"\n### q by how buried the cells are, {lo:g}–{hi:g} s (pooled over seeds)\n")
        print("contact fraction thirds: " +
              ", ".join(f"{edges[i]:.2f}–{edges[i + 1]:.2f}" for i in range(3)) + "\n")
        print("| prepared at | run | least in contact | middle | most in contact |")
        print("|---|---|---|---|---|")
        for (prep, cfg), r in t.iterrows():
            print(f"| {prep:g} | {cfg} | " + " | ".join(fmt(r.get(i)) for i in range(3)) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
