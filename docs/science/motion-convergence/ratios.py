#!/usr/bin/python3
"""The motion-convergence study's table: for each seed, integrator and Δt, the MSRD at the end
of the run (the pairs in contact at t = 0, the curve's last lag) over that of the reference
configuration of the same seed (ros2 at Δt 0.1 s): from one prepared aggregate and one noise
path, the ratio is what the discretisation keeps of the converged motion.

    docs/science/motion-convergence/ratios.py docs/science/motion-convergence/study/data \
        [--reference ros2:0.1]

Prints a Markdown table, a row per integrator, a column per Δt, "seed 1 / seed 2" in a cell, and
the reference's MSRD / r² per seed. A run that did not succeed reads "failed".
"""
import argparse
import math
import sys
from pathlib import Path

import pandas as pd

RADIUS_UM = 8.88  # the base point's cell radius (specs/fusion-2x20.toml: Table 1)


def end_msrd(msrd, job_id):
    g = msrd[msrd["job_id"] == job_id].sort_values("lag_s")
    return float(g["msrd_um2"].iloc[-1]) if len(g) else math.nan


def table(data_dir, reference):
    runs = pd.read_csv(Path(data_dir) / "runs.csv")
    msrd = pd.read_csv(Path(data_dir) / "msrd.csv.gz")
    ref_int, ref_dt = reference.split(":")
    ref_dt = float(ref_dt)
    runs["end"] = [end_msrd(msrd, j) if s == "succeeded" else math.nan
                   for j, s in zip(runs["job_id"], runs["state"])]
    seeds = sorted(runs["seed"].unique())
    ref = {}
    for s in seeds:
        r = runs[(runs["seed"] == s) & (runs["numerics.integrator"] == ref_int)
                 & (runs["numerics.dt_s"].astype(float) == ref_dt)]
        ref[s] = float(r["end"].iloc[0]) if len(r) else math.nan
    dts = sorted(runs["numerics.dt_s"].astype(float).unique())
    lines = ["| integrator (" + " / ".join(f"seed {s}" for s in seeds) + ") | "
             + " | ".join(f"Δt {d:g} s" for d in dts) + " |",
             "|---" * (len(dts) + 1) + "|"]
    for integ in dict.fromkeys(runs["numerics.integrator"]):
        cells = []
        for d in dts:
            vals = []
            for s in seeds:
                r = runs[(runs["seed"] == s) & (runs["numerics.integrator"] == integ)
                         & (runs["numerics.dt_s"].astype(float) == d)]
                if not len(r):
                    continue
                v = r["end"].iloc[0]
                vals.append("failed" if not math.isfinite(v) else f"{v / ref[s]:.2f}")
            cells.append(" / ".join(vals) if vals else "—")
        lines.append(f"| {integ} | " + " | ".join(cells) + " |")
    lines.append("")
    lines.append("reference " + reference + ", MSRD / r² at the end: "
                 + ", ".join(f"seed {s} {ref[s] / RADIUS_UM**2:.3f}" for s in seeds))
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data")
    ap.add_argument("--reference", default="ros2:0.1")
    a = ap.parse_args()
    print(table(a.data, a.reference))
    return 0


if __name__ == "__main__":
    sys.exit(main())
