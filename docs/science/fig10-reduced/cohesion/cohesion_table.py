#!/usr/bin/python3
"""The cohesion table of README.md here from a fig10-reduced report's data folder: per point, the
runs that ran the 6 h, and their medians of the shape index and θ over the last hour and of the
contact pairs per cell (`contact_pairs` / 40) and the doublet's length at the end.

    docs/science/fig10-reduced/cohesion/cohesion_table.py docs/science/fig10-reduced/data
"""
import sys

import pandas as pd


def main(data: str) -> None:
    runs = pd.read_csv(f"{data}/runs.csv")
    samples = pd.read_csv(f"{data}/samples.csv.gz")
    print("| p_a | τ_γ (s) | γ | runs that ran the 6 h | shape index | contact pairs per cell "
          "| length (µm) | θ (°) | outcomes |")
    print("|---|---|---|---|---|---|---|---|---|")
    for (pa, tg, g), point in runs.groupby(["cells.p_a", "cells.tau_gamma_s", "cells.gamma"]):
        ok = point[point.state == "succeeded"]
        end = ok.t_end_s.max() if len(ok) else 0
        last = samples[samples.job_id.isin(ok.job_id) & (samples.t_s >= end - 3600)]
        means = last.groupby("job_id").mean(numeric_only=True)
        print(f"| {pa:.4g} | {tg:g} | {g:g} | {len(ok)} of {len(point)} "
              f"| {means.shape_index_mean.median():.2f} | {(ok.contact_pairs / 40).median():.0f} "
              f"| {ok.length_um.median():.0f} | {means.theta_deg.median():.0f} "
              f"| {', '.join(sorted(set(ok.outcome)))} |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
