#!/usr/bin/python3
"""Is a point's motion caged? The local exponent of the MSRD (MSRD ∝ lag^β: β < 1 subdiffusive,
caged; β ≈ 1 diffusive; β > 1 persistent) over lag windows, per run, from a study's committed
data (runs.csv and msrd.csv.gz, written by `scripts/study.sh run … --report`). β is the
least-squares slope of log MSRD against log lag over the window's lags.

    docs/science/jam-day/msrd_exponents.py DATA_DIR [DATA_DIR…] [--windows 360:3600,3600:14400] [--where K=V…]
        [--at 600,3600]

Prints one markdown row per succeeded run: its point (the study's swept keys), seed, β in each
window, the MSRD at the longest lag and the mixing time (the study's column), then per
point the median β of each window. A jammed tissue shows β well below 1 at long lags and a
mixing time at the run's cap. --at adds each point's median MSRD / r² at those lags (r: the run's
cells.radius_mean_um where its settings set it, else 8.88 µm, as the reports divide), to set
points side by side at equal lag.
"""
import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

R_UM = 8.88  # the cell radius the studies' reports divide the MSRD by, unless a run sets its own


def radius_um(run):
    """The cell radius a run's MSRD is read against: its settings' cells.radius_mean_um, else
    the reports' default."""
    try:
        return float(json.loads(run["settings"]).get("cells.radius_mean_um", R_UM))
    except (KeyError, TypeError, ValueError):
        return R_UM


def windows_arg(text):
    out = []
    for part in text.split(","):
        lo, hi = part.split(":")
        out.append((float(lo), float(hi)))
        if not 0 < out[-1][0] < out[-1][1]:
            raise argparse.ArgumentTypeError(f"window {part!r}: need 0 < low < high (seconds)")
    return out


def slope(lags, msrd, lo, hi):
    keep = (lags >= lo) & (lags <= hi) & (msrd > 0)
    if keep.sum() < 3:
        return float("nan")
    return float(np.polyfit(np.log(lags[keep]), np.log(msrd[keep]), 1)[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", nargs="+", type=Path, help="a study's data folder")
    ap.add_argument("--windows", type=windows_arg, default=windows_arg("360:3600,3600:14400"),
                    help="lag windows in seconds, LOW:HIGH,… (default 360:3600,3600:14400)")
    ap.add_argument("--where", nargs="*", default=[],
                    help="keep runs whose column K equals V (compared as text and as number)")
    ap.add_argument("--at", default="",
                    help="lags in seconds, L1,L2,…: the points' median MSRD / r² there")
    args = ap.parse_args()
    try:
        at = [float(x) for x in args.at.split(",") if x.strip()]
    except ValueError:
        sys.exit(f"msrd_exponents: --at {args.at}: need lags in seconds, L1,L2,…")

    rows = []
    for folder in args.data:
        runs_file, msrd_file = folder / "runs.csv", folder / "msrd.csv.gz"
        for f in (runs_file, msrd_file):
            if not f.is_file():
                sys.exit(f"msrd_exponents: {f} not found (a study's data folder holds runs.csv "
                         "and msrd.csv.gz)")
        runs = pd.read_csv(runs_file)
        msrd = pd.read_csv(msrd_file)
        keys = list(runs.columns[1:list(runs.columns).index("seed")])
        for cond in args.where:
            k, _, v = cond.partition("=")
            if k not in runs.columns:
                sys.exit(f"msrd_exponents: --where {cond}: no column {k!r} in {runs_file}")
            col = runs[k]
            try:
                runs = runs[np.isclose(col.astype(float), float(v))]
            except ValueError:
                runs = runs[col.astype(str) == v]
        for _, run in runs[runs["state"] == "succeeded"].iterrows():
            m = msrd[msrd["job_id"] == run["job_id"]].sort_values("lag_s")
            if m.empty:
                continue
            lags, vals = m["lag_s"].to_numpy(float), m["msrd_um2"].to_numpy(float)
            point = ", ".join(f"{k} = {run[k]}" for k in keys)
            betas = [slope(lags, vals, lo, hi) for lo, hi in args.windows]
            rows.append({"study": folder.parent.name, "point": point, "seed": int(run["seed"]),
                         "job": run["job_id"], "betas": betas,
                         "msrd_end_um2": vals[-1],
                         "at": [float(np.interp(lag, lags, vals, left=np.nan, right=np.nan))
                                / radius_um(run) ** 2 for lag in at],
                         "mixing_time_s": run.get("mixing_time_s", float("nan")),
                         "t_end_s": run.get("t_end_s", float("nan"))})
    if not rows:
        sys.exit("msrd_exponents: no succeeded run with MSRD samples")

    names = [f"β {lo / 60:g}–{hi / 60:g} min" for lo, hi in args.windows]
    print("| study | point | seed | job | " + " | ".join(names) +
          " | MSRD at the last lag (µm²) | mixing time (s) | run length (s) |")
    print("|---|---|---|---|" + "---|" * len(names) + "---|---|---|")
    for r in rows:
        print(f"| {r['study']} | {r['point']} | {r['seed']} | {r['job']} | " +
              " | ".join(f"{b:.2f}" for b in r["betas"]) +
              f" | {r['msrd_end_um2']:.4g} | {r['mixing_time_s']:.4g} | {r['t_end_s']:.0f} |")
    print()
    at_names = [f"MSRD({lag:g} s) / r²" for lag in at]
    print("| study | point | runs | " + " | ".join(f"median {n}" for n in names + at_names) +
          " |")
    print("|---|---|---|" + "---|" * (len(names) + len(at_names)))
    groups = {}
    for r in rows:
        groups.setdefault((r["study"], r["point"]), []).append(r)
    for (study, point), rs in groups.items():
        med = [np.nanmedian([r["betas"][i] for r in rs]) for i in range(len(names))]
        med_at = [np.nanmedian([r["at"][i] for r in rs]) for i in range(len(at))]
        print(f"| {study} | {point} | {len(rs)} | " + " | ".join(f"{b:.2f}" for b in med) +
              "".join(f" | {m:.3g}" for m in med_at) + " |")


if __name__ == "__main__":
    main()
