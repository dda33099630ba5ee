#!/usr/bin/python3
"""The MSRD by depth from foam-run output folders whose spec asks for the probe
(`[observe] msrd_by_depth = true`, docs/scenes.md): per run, the buried cells (median over the
samples), the MSRD of neighbour pairs at a lag by class — both cells on the surface, one of
each, both buried, and by the shallower cell's depth in the contact graph (0, 1, 2+) — and each
burial class's mixing time beside the run's own (all pairs).

    docs/science/fig9-depth/depth_table.py RUN_DIR [RUN_DIR …] [--lag 3840]

Prints Markdown, one row per folder (labelled by its name). MSRD over r², read off the probe's
curves in summary.json (linear between lags, from 0 at lag 0; "—" past a curve's end or for a
class without pairs); a mixing time not reached within the run reads "past T s".
"""
import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

CLASSES = [("msrd_surface", "surface–surface"), ("msrd_mixed", "surface–buried"),
           ("msrd_buried", "buried–buried"), ("msrd_layer0", "depth 0"),
           ("msrd_layer1", "depth 1"), ("msrd_layer2plus", "depth 2+")]
MIXING = [("surface", "surface–surface"), ("mixed", "surface–buried"), ("buried", "buried–buried")]


def read_run(folder):
    """The folder's samples, resolved spec and summary; a run without the probe is refused."""
    folder = Path(folder)
    summary_path = folder / "summary.json"
    if not summary_path.exists():
        raise ValueError(f"{folder}: no summary.json (the run has not finished)")
    summary = json.loads(summary_path.read_text())
    if "msrd_buried" not in summary.get("curves", {}):
        raise ValueError(f"{folder}: summary.json has no msrd_buried curve "
                         "(run the spec with [observe] msrd_by_depth = true)")
    spec = json.loads((folder / "spec.json").read_text())
    samples = pd.read_csv(folder / "samples.csv")
    return samples, spec, summary


def curve_at(curve, lag_s):
    """A probe curve ({"x": lags, "y": µm²}) at lag_s; NaN past its end or with no points."""
    x, y = curve.get("x", []), curve.get("y", [])
    if not x or lag_s > x[-1] or lag_s < 0:
        return float("nan")
    return float(np.interp(lag_s, [0.0, *x], [0.0, *y]))


def mixing_text(final, key, reached_key, duration_s):
    value = final.get(key)
    if value is None or not math.isfinite(value):
        return "—"
    if not final.get(reached_key, 1):
        return f"past {duration_s:.0f} s"
    return f"{value:.0f} s"


def row(label, samples, spec, summary, lag_s):
    r2 = spec["cells"]["radius_mean_um"] ** 2
    out = {"run": label, "cells": f"2 × {spec['scene']['n_cells']}",
           "buried cells (median)": f"{samples['cells_buried'].dropna().median():.0f}"}
    for key, name in CLASSES:
        v = curve_at(summary["curves"].get(key, {}), lag_s)
        out[f"{name} at {lag_s:g} s / r²"] = f"{v / r2:.2f}" if math.isfinite(v) else "—"
    final, duration = summary.get("final_values", {}), summary.get("t_s", float("nan"))
    for cls, name in MIXING:
        out[f"mixing: {name}"] = mixing_text(final, f"mixing_time_{cls}_s",
                                             f"mixing_{cls}_reached", duration)
    out["mixing: all pairs"] = mixing_text(final, "mixing_time_s", "mixing_reached", duration)
    return out


def table(runs, lag_s):
    """runs: (label, samples, spec, summary); the Markdown table."""
    out = pd.DataFrame([row(*r, lag_s) for r in runs])
    lines = ["| " + " | ".join(out.columns) + " |", "|" + "---|" * len(out.columns)]
    lines += ["| " + " | ".join(str(v) for v in r) + " |" for r in out.itertuples(index=False)]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", nargs="+", help="foam-run output folders")
    ap.add_argument("--lag", type=float, default=3840.0, help="the MSRD's lag, s")
    a = ap.parse_args(argv)
    print(table([(Path(f).name, *read_run(f)) for f in a.run], a.lag))
    return 0


if __name__ == "__main__":
    sys.exit(main())
