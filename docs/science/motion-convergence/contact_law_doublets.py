#!/usr/bin/python3
"""The contact law on the supplement's calibration: passive doublets of equal cells settle at
θ_c = arccos α (Fig. 7E). A law that bounds pairs acts on oblique ones, which at a junction are
those of its rim, where the doublet's angle is read: this is where a law would bias the
calibration if it did. Runs doublet.toml (beside this file) with foam-run at each α and law and
prints a Markdown table: θ_c (the mean of samples every 5 s over the last 300 s), its error
against arccos α, its change from the supplement's law, the volume error at the end.

    docs/science/motion-convergence/contact_law_doublets.py [--foam-run PATH] [--set KEY=VALUE ...]

The --set pairs go to every run (e.g. numerics.dt_s=0.5). ~1 min on one core.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
# α and how long its doublet takes to settle from a 50 nm gap (s).
CASES = [(0.15, 800), (0.3, 800), (0.6, 1500), (0.9, 4500)]
LAWS = ["supplement", "prisms", "prisms-overlap"]
WINDOW_S = 300


def settled_angle(samples_csv, duration_s):
    """Mean contact_angle_deg of the samples in the last WINDOW_S seconds."""
    with open(samples_csv, newline="") as f:
        rows = list(csv.DictReader(f))
    tail = [float(r["contact_angle_deg"]) for r in rows
            if float(r["t_s"]) >= duration_s - WINDOW_S - 1e-9]
    return sum(tail) / len(tail) if tail else math.nan


def run(foam_run, alpha, duration_s, law, extra):
    with tempfile.TemporaryDirectory() as out:
        cmd = [foam_run, str(HERE / "doublet.toml"), "--out", out,
               "--set", f"cells.alpha={alpha}", "--set", f"duration_s={duration_s}",
               "--set", "sample_every_s=5", "--set", f"numerics.contact_law={law}"]
        for kv in extra:
            cmd += ["--set", kv]
        p = subprocess.run(cmd, capture_output=True, text=True,
                           env={**os.environ, "OMP_NUM_THREADS": "1"})
        summary = json.loads((Path(out) / "summary.json").read_text()) \
            if (Path(out) / "summary.json").exists() else {}
        if p.returncode != 0 or summary.get("status") not in (None, "succeeded"):
            return None, summary.get("reason") or p.stderr.strip().splitlines()[-1:]
        theta = settled_angle(Path(out) / "samples.csv", duration_s)
        return (theta, summary["final_values"]["volume_error_max"]), None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--foam-run", default=str(HERE.parents[2] / "build/release/runner/foam-run"))
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args()
    print("| α | arccos α | law | θ_c | error | change from the supplement's | volume error at the end |")
    print("|---|---|---|---|---|---|---|")
    for alpha, duration_s in CASES:
        target = math.degrees(math.acos(alpha))
        base = None
        for law in LAWS:
            res, why = run(args.foam_run, alpha, duration_s, law, args.set)
            if res is None:
                print(f"| {alpha:g} | {target:.2f}° | {law} | failed: {why} | | | |")
                continue
            theta, verr = res
            if law == "supplement":
                base = theta
            change = f"{theta - base:+.2f}°" if base is not None and law != "supplement" else ""
            print(f"| {alpha:g} | {target:.2f}° | {law} | {theta:.2f}° | {theta - target:+.2f}° "
                  f"| {change} | {100 * verr:.3f} % |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
