"""fig8's p_a r/2γ = 1 points at the default step (Δt 1 s, adaptive) against their committed
Δt 0.5 s runs (docs/science/fig8-reduced/data): how far each got, what the adaptive step and the
repairs did, and θ and the unique contacts at 1 h and 2 h. Writes the table as CSV to stdout.

    python3 docs/science/presets-pa1/compare.py RUN_DIR... > docs/science/presets-pa1/pa1.csv

where each RUN_DIR is a foam-run output folder of the point (its spec.json names α and seed).
"""
import json
import sys
from pathlib import Path

import pandas as pd

DATA = Path(__file__).resolve().parents[1] / "fig8-reduced" / "data"


def at(samples, t, col):
    row = samples[samples["t_s"] == t]
    return float(row[col].iloc[0]) if len(row) else float("nan")


def main(dirs):
    runs = pd.read_csv(DATA / "runs.csv")
    samples = pd.read_csv(DATA / "samples.csv.gz")
    rows = []
    for d in map(Path, dirs):
        spec = json.loads((d / "spec.json").read_text())
        summary = json.loads((d / "summary.json").read_text())
        alpha, seed = spec["cells"]["alpha"], spec["seed"]
        new = pd.read_csv(d / "samples.csv")
        old_run = runs[(runs["cells.pa_reduced"] == 1) & (runs["cells.alpha"] == alpha)
                       & (runs["seed"] == seed)].iloc[0]
        old = samples[samples["job_id"] == old_run["job_id"]]
        row = {"alpha": alpha, "seed": seed,
               "dt05_state": old_run["state"], "dt05_failure": old_run["failure_kind"],
               "dt05_t_end_s": old_run["t_s"],
               "dt1_failure": summary["failure"], "dt1_t_end_s": summary["t_s"],
               "dt1_steps_rejected": summary["steps_rejected"], "dt1_dt_min_s": summary["dt_min_s"],
               "dt1_remesh_rescues": summary["remesh_rescues"],
               "dt1_remesh_rebuilds": summary["remesh_rebuilds"]}
        for t in (3600, 7200):
            h = t // 3600
            row[f"dt05_theta_{h}h"] = at(old, t, "theta_deg")
            row[f"dt1_theta_{h}h"] = at(new, t, "theta_deg")
            row[f"dt05_unique_{h}h"] = at(old, t, "unique_contacts_norm")
            row[f"dt1_unique_{h}h"] = at(new, t, "unique_contacts_norm")
        rows.append(row)
    pd.DataFrame(rows).to_csv(sys.stdout, index=False, float_format="%.4g")


if __name__ == "__main__":
    main(sys.argv[1:])
