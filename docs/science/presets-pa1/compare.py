"""fig8's p_a r/2γ = 1 points at the default step (Δt 1 s, adaptive) against the same points run at
Δt 0.5 s: how far each run got, what the adaptive step and the repairs did, its diagnosis rerun,
and θ, MSRD and the unique contacts at the end. Writes the table as CSV to stdout.

    git archive 6e6aec7 docs/science/fig8-reduced/data | tar -x -C OLD
    python3 docs/science/presets-pa1/compare.py OLD/docs/science/fig8-reduced/data \\
        docs/science/fig8-reduced/data > docs/science/presets-pa1/pa1.csv

The first folder is fig8-reduced's data while its p_a r/2γ = 1 row ran Δt 0.5 s, the second its
data since that row runs the default step.
"""
import sys
from pathlib import Path

import pandas as pd


def points(data: Path) -> pd.DataFrame:
    runs = pd.read_csv(data / "runs.csv")
    return runs[runs["cells.pa_reduced"] == 1].set_index(["cells.alpha", "seed"])


def main(old_dir: str, new_dir: str) -> None:
    old, new = points(Path(old_dir)), points(Path(new_dir))
    rows = []
    for (alpha, seed), n in new.sort_index().iterrows():
        o = old.loc[(alpha, seed)]
        row = {"alpha": alpha, "seed": seed}
        for tag, r in (("dt05", o), ("dt1", n)):
            row[f"{tag}_state"] = r["state"]
            row[f"{tag}_failure"] = r["failure_kind"] if r["state"] == "failed" else ""
            row[f"{tag}_t_end_s"] = r["t_end_s"]
            row[f"{tag}_diagnosis"] = r["diagnoses"] if isinstance(r["diagnoses"], str) else ""
        row.update({"dt1_steps_rejected": n["steps_rejected"], "dt1_dt_min_s": n["dt_min_s"],
                    "dt1_remesh_rescues": n["remesh_rescues"],
                    "dt1_remesh_rebuilds": n["remesh_rebuilds"]})
        for tag, r in (("dt05", o), ("dt1", n)):
            ok = r["state"] == "succeeded"
            row[f"{tag}_theta_end_deg"] = r["theta_deg"] if ok else float("nan")
            row[f"{tag}_unique_end"] = r["unique_contacts_norm"] if ok else float("nan")
        rows.append(row)
    pd.DataFrame(rows).to_csv(sys.stdout, index=False, float_format="%.4g")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: compare.py OLD_DATA NEW_DATA")
    main(sys.argv[1], sys.argv[2])
