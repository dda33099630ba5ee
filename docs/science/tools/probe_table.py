#!/usr/bin/python3
"""The probes' tables from foam-run output folders whose spec asks for the dissipation probe
(`[observe] dissipation = true`, docs/scenes.md). Per run: the median share of the power each
friction term dissipates (medians over the samples: a contact snapping now and then spikes the
springs' part for one sample); the active forces' share of the forces' power; where the probe
gives each cell's affine part, the contact friction's share of the dissipation at the cells'
scale, that dissipation's split by term and the share of the cortex's dissipation in
vertex-scale ripples (`diss_cortex_jitter_nw`); for a finished fusion, its MSRD at the end and at each --lags lag (the pooled curve of
summary.json, over r²) and its mixing time; with `rigid_motion`, the aggregate's turn and drift
at the end; with `torque`, the median rigid spin of the solved velocities, the largest net
torque of the forces and the medium's torque's median split into cortex, friction and springs.

    docs/science/tools/probe_table.py RUN_DIR [RUN_DIR …] [--lags 600,1800,3000]

Prints Markdown, one row per folder (labelled by its name, with ξ from its spec.json). The power
balance (the terms' sum against vᵀF) is checked per sample and its worst relative error printed.
"""
import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

TERMS = ["diss_medium_nw", "diss_cortex_nw", "diss_friction_t_nw", "diss_friction_n_nw",
         "diss_springs_nw"]
LABELS = ["medium", "cortex", "friction ∥", "friction ⊥", "springs (implicit)"]
# Each cell's affine part of v (motion at the cells' scale), where the probe has them.
AFFINE = ["diss_medium_affine_nw", "diss_cortex_affine_nw", "diss_friction_t_affine_nw",
          "diss_friction_n_affine_nw"]
# The cortex's dissipation in vertex-scale ripples that move no cell (its part off the affine).
JITTER = "diss_cortex_jitter_nw"


def read_run(folder):
    """The folder's samples (the rows with a step: t = 0 has none) and its resolved spec."""
    folder = Path(folder)
    samples = pd.read_csv(folder / "samples.csv")
    missing = [c for c in TERMS + ["power_forces_nw"] if c not in samples.columns]
    if missing:
        raise ValueError(f"{folder}: samples.csv lacks {', '.join(missing)} "
                         "(run the spec with [observe] dissipation = true)")
    spec = json.loads((folder / "spec.json").read_text())
    summary = folder / "summary.json"
    if summary.exists():  # a finished run: its MSRD curve and mixing time travel with the spec
        spec = {**spec, "_summary": json.loads(summary.read_text())}
    return samples.dropna(subset=TERMS), spec


TORQUE_SHARES = ["torque_share_cortex", "torque_share_friction", "torque_share_springs"]


def msrd_at(summary, lag_s):
    """The pooled MSRD curve of summary.json at lag_s, µm² (linear between its lags, from 0 at
    lag 0; NaN past its longest or where the run has none)."""
    curve = summary.get("msrd", {})
    lags, vals = curve.get("lag_s", []), curve.get("msrd_um2", [])
    if not lags or lag_s > lags[-1] or lag_s < 0:
        return float("nan")
    return float(np.interp(lag_s, [0.0, *lags], [0.0, *vals]))


def table(runs, lags=()):
    """runs: (label, samples, spec) triples; lags: MSRD lags (s) to print. Returns the Markdown
    table and the worst balance."""
    rows, balance = [], 0.0
    for label, d, spec in runs:
        total = d[TERMS].sum(axis=1)
        if len(d):
            balance = max(balance, float(((total - d["power_forces_nw"]).abs()
                                          / d["power_forces_nw"].abs()).max()))
        share = d[TERMS].div(total, axis=0).median()
        row = {"run": label, "ξ (kPa·s/µm)": f"{spec['cells']['xi']:.4g}", "samples": len(d)}
        for t, name in zip(TERMS, LABELS):
            row[f"{name} %"] = f"{100 * share[t]:.0f}" if len(d) else "—"
        active = (d["power_active_nw"] / d["power_forces_nw"]).median() if len(d) else float("nan")
        row["active / forces %"] = f"{100 * active:.0f}" if len(d) else "—"
        if all(c in d.columns for c in AFFINE) and len(d):
            aff = d[AFFINE]
            fric = (aff[AFFINE[2]] + aff[AFFINE[3]]).div(aff.sum(axis=1)).median()
            row["friction's share at the cells' scale %"] = f"{100 * fric:.0f}"
            split = aff.div(aff.sum(axis=1), axis=0).median()
            row["cells' scale: medium / cortex / friction ∥ / ⊥ %"] = " / ".join(
                f"{100 * split[c]:.0f}" for c in AFFINE)
        if JITTER in d.columns and len(d):
            ripple = (d[JITTER] / d["diss_cortex_nw"]).median()
            row["cortex's ripples %"] = f"{100 * ripple:.0f}"
        summ = spec.get("_summary", {})
        if summ.get("msrd", {}).get("msrd_um2"):
            r = spec["cells"]["radius_mean_um"]
            row["MSRD at the end / r²"] = f"{summ['msrd']['msrd_um2'][-1] / r**2:.3g}"
            mix = summ.get("final_values", {}).get("mixing_time_s")
            row["mixing (s)"] = f"{mix:.0f}" if mix is not None else "—"
            for lag in lags:
                v = msrd_at(summ, lag)
                row[f"MSRD({lag:g} s) / r²"] = f"{v / r**2:.3g}" if np.isfinite(v) else "—"
        if "rigid_turn_deg" in d.columns and len(d):
            row["turn (°)"] = f"{d['rigid_turn_deg'].iloc[-1]:.3g}"
            row["drift (µm)"] = f"{d['rigid_drift_um'].iloc[-1]:.3g}"
        if "rigid_spin_deg_h" in d.columns and len(d):
            row["spin (°/h)"] = f"{d['rigid_spin_deg_h'].median():.2g}"
            row["max |net torque| (nN·µm)"] = f"{d['net_torque_nnum'].abs().max():.2g}"
            for c, name in zip(TORQUE_SHARES, ["cortex", "friction", "springs"]):
                row[f"medium's torque: {name} %"] = f"{100 * d[c].median():.0f}"
        rows.append(row)
    out = pd.DataFrame(rows).fillna("—")
    lines = ["| " + " | ".join(out.columns) + " |", "|" + "---|" * len(out.columns)]
    lines += ["| " + " | ".join(str(v) for v in r) + " |" for r in out.itertuples(index=False)]
    return "\n".join(lines), balance


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", nargs="+", help="foam-run output folders")
    ap.add_argument("--lags", default="", help="MSRD lags to print, s (comma-separated)")
    a = ap.parse_args(argv)
    lags = [float(x) for x in a.lags.split(",") if x.strip()]
    runs = [(Path(f).name, *read_run(f)) for f in a.run]
    text, balance = table(runs, lags)
    print(text)
    print(f"\nPower balance: the terms' sum is vᵀF within {100 * balance:.2g} % at every sample.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
