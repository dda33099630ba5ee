#!/usr/bin/env python3
"""Whole-step cost of a named scene (a spec) under several numerics, through foam-run.

  bench/step_cost.py run FOAM_RUN SPEC OUT [--cache DIR] [--threads N] [--duration S] \\
      'NAME|--set K=V ...' ...
  bench/step_cost.py table RUN_DIR ...

`run` runs foam-run once per configuration, one after the other, into OUT/NAME (log: OUT/NAME.log),
each from the same prepared spheroids (CACHE, foam-run --spheroid-cache; prepared on first use,
untimed), for S simulated seconds (default 20; a configuration's own `--set duration_s=` wins),
sampling only at t = 0 and at the end, with no snapshots or checkpoints; then prints the table.
`table` prints the table of finished foam-run folders (the name is the folder's).

One markdown row a run: the numerics (spec.json), steps, CG iterations a step (summary.json's
cg_iters_mean), ms a step and its phases (summary.json's phase_wall_s a step), the wall time a
simulated minute and a simulated day would take at this pace.

What is timed. summary.json's wall_s runs from the engine's start of the run, so it holds the
spheroids' loading from the cache (or their preparation, on a miss) and the scene's setup; the
first row of samples.csv (t = 0) is written after them, so its wall_s is subtracted: ms a step is
(wall_s − samples.csv's wall_s at t = 0) / steps. The phases are accumulated inside the steps
only and need no correction; what a step spends outside them (guards, moving the vertices, the
end sample) is in ms a step and in no phase. Every step counts, the first ones included: CG
starts the first step from rest, so it takes about twice the iterations and the time of a later
one (2 × 20, consistent step at Δt 0.5 s), which adds a few per cent to the means of 30 steps
and under one per cent to those of 200. With an adaptive step the simulated time (summary.json's
t_s) makes the projections, not Δt.
"""
import argparse
import csv
import json
import os
import shlex
import subprocess
import sys
from pathlib import Path

PHASES = ("geometry", "contacts", "forces", "matrix", "solve", "remesh")

HEADER = (
    "| run | integrator | Δt (s) | preconditioner | ε_CG | steps | CG iters/step | ms/step | "
    + " | ".join(PHASES)
    + " | wall per simulated min | projected 24 h |"
)


class RunError(Exception):
    """A folder that is not a finished foam-run run."""


def read_run(folder):
    """The cost of one foam-run folder, as a dict (see row())."""
    folder = Path(folder)

    def read(name, parse):
        try:
            with open(folder / name, newline="") as f:
                return parse(f)
        except FileNotFoundError:
            raise RunError(f"{folder}: no {name} (not a finished foam-run run)") from None
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise RunError(f"{folder / name}: {e}") from e

    summary = read("summary.json", json.load)
    numerics = read("spec.json", lambda f: json.load(f)["numerics"])

    def first_wall(f):
        first = next(csv.DictReader(f), None)
        if first is None or float(first["t_s"]) != 0:
            raise ValueError("no sample at t = 0")
        return float(first["wall_s"])

    setup_s = read("samples.csv", first_wall)
    for key in ("steps", "t_s", "wall_s", "cg_iters_mean", "phase_wall_s"):
        if summary.get(key) is None:
            raise RunError(f"{folder / 'summary.json'}: no {key}")
    return {
        "name": folder.name,
        "integrator": numerics.get("integrator", "?"),
        "dt_s": numerics.get("dt_s"),
        "preconditioner": numerics.get("preconditioner", "?"),
        "cg_tol": numerics.get("cg_tol"),
        "steps": int(summary["steps"]),
        "t_s": float(summary["t_s"]),
        "timed_s": float(summary["wall_s"]) - setup_s,
        "setup_s": setup_s,
        "cg_iters": float(summary["cg_iters_mean"]),
        "phases_s": {p: float(summary["phase_wall_s"].get(p, 0.0)) for p in PHASES},
        "ok": bool(summary.get("ok", False)),
        "failure": summary.get("failure", ""),
    }


def row(r):
    """One markdown row: ms a step and its phases, and the projected wall times."""
    n = r["steps"]
    ms = lambda s: f"{1e3 * s / n:.1f}" if n else "—"  # noqa: E731
    per_step = f"{1e3 * r['timed_s'] / n:.0f}" if n else "—"
    if r["t_s"] > 0:
        pace = r["timed_s"] / r["t_s"]  # wall seconds a simulated second
        per_min = f"{pace:.1f} min"
        per_day = f"{pace * 86400 / 3600:.0f} h"
    else:
        per_min = per_day = "—"
    cells = [r["name"], r["integrator"], f"{r['dt_s']:g}", r["preconditioner"],
             f"{r['cg_tol']:g}", str(n), f"{r['cg_iters']:.1f}", per_step,
             *(ms(r["phases_s"][p]) for p in PHASES), per_min, per_day]
    line = "| " + " | ".join(cells) + " |"
    if not r["ok"]:
        line += f" failed: {r['failure']}"
    return line


def table(runs):
    return "\n".join([HEADER, "|" + "---|" * HEADER.count(" | ") + "---|"]
                     + [row(r) for r in runs])


def setting(words, key):
    """The value the last `--set key=V` of `words` gives, or None."""
    value = None
    for flag, arg in zip(words, words[1:]):
        if flag == "--set" and arg.startswith(key + "="):
            value = arg.split("=", 1)[1]
    return value


def parse_config(text):
    """'NAME|--set K=V ...' → (NAME, words); without NAME, the settings' values name it."""
    name, bar, sets = text.partition("|")
    if not bar:
        sets = text
    words = shlex.split(sets)
    if not bar:
        name = "_".join(w.split("=", 1)[-1] for w in words if w != "--set")
    name = "".join(c if c.isalnum() or c in ".-" else "_" for c in name.strip()) or "run"
    return name, words


def foam_run_command(foam_run, spec, folder, cache, threads, duration, words):
    duration = setting(words, "duration_s") or f"{duration:g}"
    sample = setting(words, "sample_every_s") or duration
    cmd = [foam_run, spec, "--out", str(folder), "--force", "--threads", str(threads), "-q",
           "--checkpoint-every", "0"]
    if cache:
        cmd += ["--spheroid-cache", cache]
    return cmd + ["--set", f"duration_s={duration}", "--set", f"sample_every_s={sample}",
                  "--set", "snapshot_every_s=0"] + words


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="mode", required=True)
    r = sub.add_parser("run", help="run the configurations, then print their table")
    r.add_argument("foam_run")
    r.add_argument("spec")
    r.add_argument("out")
    r.add_argument("configs", nargs="+", help="'NAME|--set K=V ...'")
    r.add_argument("--cache", default="", help="foam-run --spheroid-cache (default: foam-run's)")
    r.add_argument("--threads", type=int, default=1)
    r.add_argument("--duration", type=float, default=20.0, help="simulated seconds")
    t = sub.add_parser("table", help="print the table of finished foam-run folders")
    t.add_argument("runs", nargs="+")
    a = ap.parse_args(argv)

    if a.mode == "table":
        try:
            print(table([read_run(f) for f in a.runs]))
        except RunError as e:
            sys.exit(f"step_cost.py: {e}")
        return 0

    configs = [parse_config(c) for c in a.configs]
    names = [n for n, _ in configs]
    if len(set(names)) != len(names):
        sys.exit(f"step_cost.py: configuration names repeat ({', '.join(names)})")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, OMP_NUM_THREADS=str(a.threads))
    print(HEADER + "\n|" + "---|" * HEADER.count(" | ") + "---|", flush=True)
    failed = 0
    for name, words in configs:
        cmd = foam_run_command(a.foam_run, a.spec, out / name, a.cache, a.threads, a.duration,
                               words)
        # A spec foam-run refuses leaves an earlier run's files: none may pass for this one's.
        (out / name / "summary.json").unlink(missing_ok=True)
        with open(out / f"{name}.log", "w") as log:
            log.write(shlex.join(cmd) + "\n")
            log.flush()
            code = subprocess.call(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)
        try:
            print(row(read_run(out / name)), flush=True)
        except RunError as e:
            failed += 1
            print(f"step_cost.py: {name}: foam-run exit {code}, {e}; see {out / name}.log",
                  file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
