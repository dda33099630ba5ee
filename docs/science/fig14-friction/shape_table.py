#!/usr/bin/python3
"""Where the shape index's rise with friction comes from, from the runs of shape-runs.txt
(foam-run folders NAME-seedS whose spec asks for the shape probe, `[observe] shape = true`;
one that has not finished, with no summary.json, is left out).

    docs/science/fig14-friction/shape_table.py OUT [--windows 0:0,3000:3600] [--pair A|B ...]

Prints Markdown, per window (means over the window's samples):
  1. each run's shape index q, its smoothed value (vertex-scale ripples removed), their
     difference, the cells' elongation, their contact fraction f and θ;
  2. the paired differences A − B (same seed: the same aggregate and polarity noise), with the
     part of Δq that the change of contact fraction accounts for: the slope of the cells' q on
     their f (the probe's line through the cells, mean of the two runs') × Δf; and per pair the
     median and range over seeds;
  3. the line through the cells, q ≈ intercept + slope f, and its r, per run.
"""
import argparse
import re
import sys
from pathlib import Path

import pandas as pd

COLUMNS = {"shape_index_mean": "q", "shape_index_smoothed_mean": "q_smooth",
           "elongation_mean": "elong", "contact_fraction_mean": "f", "theta_deg": "theta",
           "shape_on_contact_slope": "slope", "shape_on_contact_intercept": "intercept",
           "shape_on_contact_r": "r"}
# The pairs of shape-runs.txt: each raises friction (or changes one setting) against its base.
PAIRS = ["L0.25|L2", "L0.25-prep0.25|L2", "L0.25-pa0|L2-pa0", "L2-pa0|L2", "L0.25-xin2|L2",
         "L2-xin0.25|L2", "L0.25-alpha0.4375|L2-alpha0.4375", "L0.5-taup2400|L0.5-taup150",
         "L0.25-mesh1280|L2-mesh1280", "L0.25-n50|L2-n50", "L0.25-reference|L2-reference"]


def load(out):
    """All runs under OUT as one frame with columns name, seed, t_s and COLUMNS' short names."""
    frames = []
    for d in sorted(Path(out).iterdir()):
        m = re.fullmatch(r"(.+)-seed(\d+)", d.name)
        if not m or not (d / "samples.csv").exists():
            continue
        if not (d / "summary.json").exists():
            print(f"shape_table.py: {d.name} has not finished; left out", file=sys.stderr)
            continue
        s = pd.read_csv(d / "samples.csv")
        missing = [c for c in COLUMNS if c not in s.columns]
        if missing:
            raise ValueError(f"{d}: samples.csv lacks {', '.join(missing)} "
                             "(run the spec with [observe] shape = true)")
        s = s[["t_s"] + list(COLUMNS)].rename(columns=COLUMNS)
        s["name"], s["seed"] = m.group(1), int(m.group(2))
        frames.append(s)
    if not frames:
        raise ValueError(f"{out}: no finished NAME-seedS folder (samples.csv, summary.json)")
    return pd.concat(frames, ignore_index=True)


def window_means(runs, lo, hi):
    w = runs[(runs.t_s >= lo) & (runs.t_s <= hi)].copy()
    w["ripple"] = w.q - w.q_smooth
    return w.groupby(["name", "seed"]).mean(numeric_only=True).drop(columns="t_s")


def paired(m, a, b):
    """Rows (seed, difference of the window means, its contact part) of A − B by seed."""
    names = set(m.index.get_level_values(0))
    if a not in names or b not in names:
        return []
    rows = []
    for seed in sorted(set(m.loc[a].index) & set(m.loc[b].index)):
        d = m.loc[(a, seed)] - m.loc[(b, seed)]
        k = (m.loc[(a, seed)].slope + m.loc[(b, seed)].slope) / 2
        rows.append((seed, d, k * d.f))
    return rows


def span(values, digits=4):
    v = pd.Series(values)
    return f"{v.median():+.{digits}f} ({v.min():+.{digits}f} to {v.max():+.{digits}f})"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--windows", default="0:0,3000:3600")
    ap.add_argument("--pair", action="append", default=None, help="A|B (A − B); default: "
                    "the pairs of shape-runs.txt that are there")
    a = ap.parse_args(argv)
    runs = load(a.out)
    pairs = [tuple(p.split("|")) for p in (a.pair or PAIRS)]
    for lo, hi in [tuple(float(v) for v in w.split(":")) for w in a.windows.split(",")]:
        m = window_means(runs, lo, hi)
        print(f"\n### {lo:g}–{hi:g} s\n")
        print("| run | seed | q | q smoothed | q − smoothed | elongation | contact fraction f "
              "| θ (°) | q on f: intercept + slope f (r) |")
        print("|---|---|---|---|---|---|---|---|---|")
        for (name, seed), r in m.iterrows():
            print(f"| {name} | {seed} | {r.q:.4f} | {r.q_smooth:.4f} | {r.ripple:.4f} | "
                  f"{r.elong:.4f} | {r.f:.3f} | {r.theta:.1f} | "
                  f"{r.intercept:.2f} + {r.slope:.2f} f ({r.r:.2f}) |")
        summary = []
        for pa, pb in pairs:
            rows = paired(m, pa, pb)
            if not rows:
                continue
            if not summary:
                print(f"\nPaired differences (same aggregate and noise), {lo:g}–{hi:g} s:\n")
                print("| difference | seed | Δq | Δq smoothed | Δ(q − smoothed) | Δelongation "
                      "| Δf | slope × Δf (contact part of Δq) |")
                print("|---|---|---|---|---|---|---|---|")
            for seed, d, part in rows:
                print(f"| {pa} − {pb} | {seed} | {d.q:+.4f} | {d.q_smooth:+.4f} | "
                      f"{d.ripple:+.4f} | {d.elong:+.4f} | {d.f:+.4f} | {part:+.4f} |")
            seeds = f"{len(rows)} seed" + ("s" if len(rows) > 1 else "")
            summary.append(f"{pa} − {pb} ({seeds}): Δq {span([d.q for _, d, _ in rows])}, "
                           f"Δf {span([d.f for _, d, _ in rows])}, contact part "
                           f"{span([p for _, _, p in rows])}")
        if summary:
            print("\nAcross seeds (median, min to max):\n")
            print("\n".join(f"- {s}" for s in summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
