#!/usr/bin/env python3
"""Speed against accuracy on a reduced fusion: two spheroids of 30 cells fusing for `--hours`
simulated hours, each numerical knob varied alone from BASE (contact-implicit, Δt 0.5 s) and
measured against a reference solved at the finest settings that fit the machine.

    docs/study/fusion_accuracy.py OUT_DIR [--hours H] [--cells N] [--only NAME,...]
        [--foam-run PATH] [--report-only]

Every configuration is one `foam-run ... --resume` into OUT_DIR/runs/NAME with checkpoints, so
the study survives interruptions: run the same command again and it continues where it stopped
(finished runs are skipped). All runs share one spheroid cache (OUT_DIR/cache): the solver knobs
start from the same prepared aggregates; 80 triangles per cell needs its own.

Reference: contact-implicit, Δt = 0.1 s (the supplement's), ε_CG = 1e-6, 320 triangles per cell.
1 280 triangles (the finest mesh studied) does not fit this 2-core machine for a fusion (~4× the
vertices and contacts: ~7 h of wall time per simulated hour); the doublet study has it.

Writes OUT_DIR/fusion.csv and OUT_DIR/fusion.md: per configuration the θ(t) error against the
reference (RMS and max over the common samples), θ_eq and τ_f of the Eq. 1 fits and their
differences, the largest cell volume error, wall time per simulated hour and peak memory.
Chart: docs/study/plot_study.py OUT_DIR/fusion.csv OUT_DIR/fusion-pareto.png "fusion 2 x 30".
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys

BASE = {
    "scene": "fusion",
    "seed": 1,
    "sample_every_s": 30,
    "snapshot_every_s": 0,
    "scene.prep_max_s": 600,
    "numerics.integrator": "contact-implicit",
    "numerics.dt_s": 0.5,
    "numerics.cg_tol": 1e-3,
    "numerics.triangles_per_cell": 320,
    "numerics.preconditioner": "jacobi",
    "numerics.contact_quadrature": "exact",
}

# name, knob, overrides of BASE (the reference first). BASE (row `draft`) is the one-spring
# contact-implicit step at Δt 0.5 s, ε_CG 1e-3, Jacobi; every knob row changes one setting of it.
# Row `standard` is BASE at Δt 0.1 s. The row names are those of docs/study/fusion/fusion.md.
CONFIGS = [
    ("reference", "reference", {"numerics.dt_s": 0.1, "numerics.cg_tol": 1e-6}),
    ("draft", "preset", {}),
    ("standard", "preset", {"numerics.dt_s": 0.1}),
    ("dt-0.25", "dt", {"numerics.dt_s": 0.25}),
    ("dt-1", "dt", {"numerics.dt_s": 1.0}),
    ("cg-1e-2", "cg_tol", {"numerics.cg_tol": 1e-2}),
    ("cg-1e-5", "cg_tol", {"numerics.cg_tol": 1e-5}),
    ("block-jacobi", "preconditioner", {"numerics.preconditioner": "block-jacobi"}),
    ("centroid", "quadrature", {"numerics.contact_quadrature": "centroid"}),
    ("remesh-x4", "remesh", {"remesh_factor": 4}),
    ("mesh-80", "mesh", {"numerics.triangles_per_cell": 80}),
    # 80 triangles at Δt = 0.5 s end in volume drift: where does that start?
    ("mesh-80-dt-0.1", "mesh", {"numerics.triangles_per_cell": 80, "numerics.dt_s": 0.1}),
    ("mesh-80-dt-0.25", "mesh", {"numerics.triangles_per_cell": 80, "numerics.dt_s": 0.25}),
    # The doublet study's Pareto front: 1 280 triangles at Δt = 0.5 s beat 320 at 0.1 s there.
    ("mesh-1280", "mesh", {"numerics.triangles_per_cell": 1280}),
    # The second-order two-stage step (two solves per step).
    ("ros2", "integrator", {"numerics.integrator": "ros2"}),
    ("ros2-dt-1", "integrator", {"numerics.integrator": "ros2", "numerics.dt_s": 1.0}),
    ("ros2-dt-0.25", "integrator", {"numerics.integrator": "ros2", "numerics.dt_s": 0.25}),
    # The contact stiffness k_AB as a numerical knob (h0 = √(W/k_AB) grows as
    # k_AB shrinks; the supplement says h0 ≪ R does not matter). Softer springs, fewer CG
    # iterations; the rows at Δt = 0.1 s separate the model change from the Δt error.
    ("kab-0.25", "k_contact", {"cells.k_contact": 71.1 / 4}),
    ("kab-0.0625", "k_contact", {"cells.k_contact": 71.1 / 16}),
    ("standard-kab-0.0625", "k_contact", {"numerics.dt_s": 0.1, "cells.k_contact": 71.1 / 16}),
    # The block incomplete-Cholesky preconditioner (same solution within ε_CG).
    ("ic", "preconditioner", {"numerics.preconditioner": "incomplete-cholesky"}),
    ("ros2-ic", "integrator", {"numerics.integrator": "ros2",
                               "numerics.preconditioner": "incomplete-cholesky"}),
    ("ros2-dt-1-ic", "integrator", {"numerics.integrator": "ros2", "numerics.dt_s": 1.0,
                                    "numerics.preconditioner": "incomplete-cholesky"}),
    # The 3×3 block-Jacobi preconditioner at ε_CG 1e-2 and at Δt 0.1 s, each beside its Jacobi
    # row run by the same engine (same ε_CG: the same residual).
    ("standard-jacobi", "preconditioner", {"numerics.dt_s": 0.1}),
    ("draft-cg-1e-2", "cg_tol", {"numerics.cg_tol": 1e-2}),
    ("draft-cg-1e-2-block-jacobi", "preconditioner", {"numerics.cg_tol": 1e-2,
                                                      "numerics.preconditioner": "block-jacobi"}),
    ("standard-block-jacobi", "preconditioner", {"numerics.dt_s": 0.1,
                                                 "numerics.preconditioner": "block-jacobi"}),
]


def value(v):
    return json.dumps(v) if isinstance(v, str) else repr(v)


def run_config(args, name, overrides, out):
    run_dir = os.path.join(out, "runs", name)
    spec = dict(BASE)
    spec["duration_s"] = args.hours * 3600
    spec["scene.n_cells"] = args.cells
    remesh = overrides.get("remesh_factor")
    spec.update({k: v for k, v in overrides.items() if k != "remesh_factor"})
    if remesh:
        spec["numerics.remesh_every_s"] = remesh * default_remesh_every(args)
    cmd = [args.foam_run, "-", "--out", run_dir, "--resume", "--checkpoint-every", "120",
           "--spheroid-cache", os.path.join(out, "cache"), "-q"]
    for k, v in spec.items():
        cmd += ["--set", f"{k}={value(v)}"]
    os.makedirs(os.path.dirname(run_dir), exist_ok=True)
    print(f"study: {name}: {' '.join(cmd[3:])}", file=sys.stderr, flush=True)
    p = subprocess.Popen(cmd, stdin=subprocess.PIPE, env=dict(os.environ, OMP_NUM_THREADS="1"))
    p.stdin.write(b'scene = "fusion"\n')
    p.stdin.close()
    _, status, usage = os.wait4(p.pid, 0)
    rc = os.waitstatus_to_exitcode(status)
    rss_file = os.path.join(run_dir, "peak_rss_mb")
    rss = usage.ru_maxrss / 1024.0
    if os.path.exists(rss_file):
        rss = max(rss, float(open(rss_file).read()))
    if os.path.isdir(run_dir):
        with open(rss_file, "w") as f:
            f.write(f"{rss:.1f}\n")
    if rc == 130:
        sys.exit("study: interrupted; run the same command again to continue")
    return rc


def default_remesh_every(args):
    """τ_r as the engine derives it (5 τ_shell of the default cells), from a resolved spec."""
    tmp = os.path.join(args.out, "runs", ".tau_r")
    subprocess.run([args.foam_run, "-", "--out", tmp, "--force", "-q", "--set", "duration_s=0.1",
                    "--set", "sample_every_s=0.1"], input=b'scene = "cell"\n', check=True)
    with open(os.path.join(tmp, "spec.json")) as f:
        return json.load(f)["numerics"]["remesh_every_s"]


def read_run(out, name):
    d = os.path.join(out, "runs", name)
    try:
        with open(os.path.join(d, "summary.json")) as f:
            summary = json.load(f)
        with open(os.path.join(d, "samples.csv")) as f:
            rows = list(csv.DictReader(f))
    except (OSError, json.JSONDecodeError):
        return None
    theta = {round(float(r["t_s"]), 6): float(r["theta_deg"]) for r in rows
             if r["theta_deg"] not in ("", "nan")}
    # Cost from the samples' wall clock: the median over the sample intervals of wall time per
    # simulated time. The spheroid preparation (paid once per aggregate by whichever run comes
    # first) is not in it, nor an interval across a resume where an older foam-run restarted its
    # wall clock (negative), nor one in which the run was paused (SIGSTOP while CI ran).
    rates = []
    for a, b in zip(rows, rows[1:]):
        dw = float(b["wall_s"]) - float(a["wall_s"])
        dt = float(b["t_s"]) - float(a["t_s"])
        if dw > 0 and dt > 0:
            rates.append(dw / dt)
    rates.sort()
    cost = rates[len(rates) // 2] * 3600 if rates else math.nan
    rss = None
    if os.path.exists(os.path.join(d, "peak_rss_mb")):
        rss = float(open(os.path.join(d, "peak_rss_mb")).read())
    return {"summary": summary, "theta": theta, "rss": rss, "cost": cost}


def fit(summary, key):
    v = summary.get(key)
    return float(v) if isinstance(v, (int, float)) else math.nan


def report(args, out):
    runs = {name: read_run(out, name) for name, _, _ in CONFIGS}
    ref = runs["reference"]
    rows = []
    for name, knob, overrides in CONFIGS:
        r = runs[name]
        if r is None:
            continue
        s = r["summary"]
        outcome = "ok" if s.get("ok") else (s.get("failure") or "unfinished")
        common = sorted(set(r["theta"]) & set(ref["theta"])) if ref else []
        diffs = [abs(r["theta"][t] - ref["theta"][t]) for t in common]
        rms = math.sqrt(sum(d * d for d in diffs) / len(diffs)) if diffs else math.nan
        mx = max(diffs) if diffs else math.nan
        t_s = float(s.get("t_s") or 0)
        cost = r["cost"]
        spec = dict(BASE)
        spec.update(overrides)
        te, tf = fit(s, "theta_eq_deg"), fit(s, "tau_f_s")
        rows.append({
            "knob": knob, "name": name, "integrator": spec["numerics.integrator"],
            "dt_s": spec["numerics.dt_s"], "triangles": spec["numerics.triangles_per_cell"],
            "cg_tol": spec["numerics.cg_tol"], "preconditioner": spec["numerics.preconditioner"],
            "quadrature": spec["numerics.contact_quadrature"],
            "remesh_factor": overrides.get("remesh_factor", 1), "outcome": outcome,
            "t_end_s": t_s, "theta_end_deg": r["theta"][max(r["theta"])] if r["theta"] else math.nan,
            "trajectory_rms_deg": 0.0 if name == "reference" else rms,
            "trajectory_max_deg": 0.0 if name == "reference" else mx,
            "theta_eq_deg": te, "tau_f_s": tf,
            "theta_eq_error_deg": abs(te - fit(ref["summary"], "theta_eq_deg")) if ref else math.nan,
            "tau_f_error_s": abs(tf - fit(ref["summary"], "tau_f_s")) if ref else math.nan,
            "volume_error_max": dict(s.get("final_values", {})).get("volume_error_max", math.nan),
            "wall_per_sim_hour_s": cost, "peak_rss_mb": r["rss"] if r["rss"] else math.nan,
        })
    for r in rows:
        ok = r["outcome"] == "ok" and r["knob"] != "reference"
        r["pareto"] = int(ok and not any(
            q is not r and q["outcome"] == "ok" and q["knob"] != "reference"
            and q["wall_per_sim_hour_s"] <= r["wall_per_sim_hour_s"]
            and q["trajectory_rms_deg"] <= r["trajectory_rms_deg"]
            and (q["wall_per_sim_hour_s"] < r["wall_per_sim_hour_s"]
                 or q["trajectory_rms_deg"] < r["trajectory_rms_deg"]) for q in rows))
    fields = list(rows[0].keys()) if rows else []
    with open(os.path.join(out, "fusion.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.4g}" if isinstance(v, float) else v) for k, v in r.items()})
    with open(os.path.join(out, "fusion.md"), "w") as f:
        f.write(f"# Speed against accuracy: fusion of 2 × {args.cells} cells\n\n"
                f"{args.hours:g} simulated hour(s) from the same prepared spheroids (seed 1); "
                "θ(t) sampled every 30 s. Reference: contact-implicit, Δt = 0.1 s, ε_CG = 1e-6, "
                "320 triangles per cell. `draft`: Δt = 0.5 s, ε_CG = 1e-3, Jacobi, exact "
                "quadrature; `standard`: the same at Δt = 0.1 s; each other row changes one knob "
                "of `draft`. ★ = Pareto front of cost against "
                "the θ(t) RMS error. Cost: wall time per simulated hour on one core of the "
                "2-core machine.\n\n"
                f"Generated by `docs/study/fusion_accuracy.py {out} --hours {args.hours:g} "
                f"--cells {args.cells}`.\n\n")
        f.write("| run | outcome | simulated (s) | θ(t) RMS / max error (°) | θ_eq (°) | "
                "τ_f (s) | volume error | wall per sim. h (s) | peak RSS (MB) |\n")
        f.write("|---|---|---|---|---|---|---|---|---|\n")
        for r in rows:
            f.write(f"| {r['name']}{' ★' if r['pareto'] else ''} | {r['outcome']} | "
                    f"{r['t_end_s']:.0f} | {r['trajectory_rms_deg']:.2f} / "
                    f"{r['trajectory_max_deg']:.2f} | {r['theta_eq_deg']:.1f} | "
                    f"{r['tau_f_s']:.0f} | {r['volume_error_max']:.2g} | "
                    f"{r['wall_per_sim_hour_s']:.0f} | {r['peak_rss_mb']:.0f} |\n")
    print(f"study: wrote {out}/fusion.csv and fusion.md", file=sys.stderr)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--hours", type=float, default=0.5)
    ap.add_argument("--cells", type=int, default=30)
    ap.add_argument("--only", default="", help="comma-separated run names")
    ap.add_argument("--foam-run", default="build/release/runner/foam-run")
    ap.add_argument("--report-only", action="store_true")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    if not args.report_only:
        only = set(filter(None, args.only.split(",")))
        for name, _, overrides in CONFIGS:
            if only and name not in only:
                continue
            rc = run_config(args, name, overrides, args.out)
            print(f"study: {name}: exit {rc}", file=sys.stderr, flush=True)
    report(args, args.out)


if __name__ == "__main__":
    main()
