#!/usr/bin/env python3
"""A long fusion job's page (docs/science/fusion-2x20-24h/): its record, samples, MSRD curve,
a four-panel figure and a summary, fetched from foamd.

    PYTHONPATH=build/release/python /usr/bin/python3 docs/science/tools/fusion_day_report.py JOB OUT_DIR \
        [--same-as JOB2] [--server HOST:PORT]

--same-as checks that the job's samples equal those of JOB2, another job in the same foamd
store, wherever both have them, wall time aside: a run of the same spec and seed for a shorter
duration must be the same bits. (A study's committed samples keep 16 digits, not every bit.)
Writes job.txt, spec.json (the resolved spec: `foam-run spec.json --out DIR` runs it again),
results.txt, samples.csv, msrd.csv, fusion.png and summary.md into OUT_DIR.
"""
import argparse
import json
import math
import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from activefoam import Client


def same_bits(a: pd.DataFrame, b: pd.DataFrame):
    """(rows compared, first difference or None): samples of equal t_s, every column both have
    but the wall time, compared exactly (NaN equal to NaN)."""
    cols = [c for c in a.columns if c in b.columns and c not in ("t_s", "wall_s", "job_id")]
    m = a.merge(b, on="t_s", suffixes=("", "_b"))
    for _, r in m.iterrows():
        for c in cols:
            x, y = r[c], r[c + "_b"]
            if not (x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y))):
                return len(m), (r["t_s"], c, x, y)
    return len(m), None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("job")
    ap.add_argument("out")
    ap.add_argument("--same-as", metavar="JOB2")
    ap.add_argument("--server", default=os.environ.get("FOAM_SERVER", "127.0.0.1:50051"))
    args = ap.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    c = Client(args.server)
    job = c.job(args.job)
    info = job.info()
    spec = json.loads(info.spec_json)
    state = job.state()
    res = job.results()
    s = job.samples()
    msrd = job.curve("msrd") if state == "succeeded" else pd.DataFrame(columns=["x", "y"])
    num = spec["numerics"]
    lines = [state, f"id:        {info.id}", f"scene:     {info.scene} (seed {info.seed}, "
             f"{spec['scene']['n_cells']} + {spec['scene']['n_cells']} cells)",
             f"progress:  {100 * info.progress:.4g} % (t = {info.t_s:.0f} s, {info.steps} steps)",
             f"created:   {info.created_utc}", f"started:   {info.started_utc}",
             f"finished:  {info.finished_utc}", f"attempts:  {info.attempts}",
             f"engine:    {info.engine_version}",
             f"numerics:  {num['integrator']}, Δt {num['dt_s']} s, ε_CG {num['cg_tol']}, "
             f"{num['triangles_per_cell']} triangles, {num['preconditioner']}",
             f"outcome:   {info.outcome}", f"tag:       {info.tag}"]
    (out / "job.txt").write_text("\n".join(lines) + "\n")
    (out / "spec.json").write_text(json.dumps(spec, indent=2, sort_keys=True) + "\n")
    (out / "results.txt").write_text(
        "".join(f"{k:26s} {v:.6g}\n" for k, v in sorted(res.items())))
    s.to_csv(out / "samples.csv", index=False)
    msrd.rename(columns={"x": "lag_s", "y": "msrd_um2"}).to_csv(out / "msrd.csv", index=False)

    h = s["t_s"] / 3600
    r_cell = float(spec["cells"]["radius_mean_um"])   # MSRD in units of the cell radius²
    fig, ax = plt.subplots(2, 2, figsize=(11, 7.5))
    a = ax[0, 0]
    a.plot(h, s["theta_deg"], ".", ms=2, label="θ(t), samples")
    if res.get("eq1_ok", 0) == 1:
        te, t0, tf = res["theta_eq_deg"], res["theta0_deg"], res["tau_f_s"]
        t = np.linspace(0, s["t_s"].max(), 600)
        a.plot(t / 3600, te + (t0 - te) * np.exp(-t / tf), "r-",
               label=f"Eq. 1: θ_eq = {te:.1f}°, τ_f = {tf:.0f} s")
    a.set(xlabel="t (h)", ylabel="θ (°)", title="fusion angle")
    a.legend(fontsize=8)
    a = ax[0, 1]
    a.plot(h, s["shape_index_mean"], label="shape index")
    a.set(xlabel="t (h)", ylabel="shape index (mean over cells)")
    a2 = a.twinx()
    a2.plot(h, s["unique_contacts_norm"], color="C2", label="unique contacts / initial")
    a2.set_ylabel("unique contacts (normalised)", color="C2")
    a.set_title("cell shape and neighbour exchange")
    a = ax[1, 0]
    if len(msrd):
        ok = msrd[(msrd["x"] > 0) & (msrd["y"] > 0)]
        a.loglog(ok["x"] / 3600, ok["y"] / r_cell ** 2, label="MSRD / r²")
        a.axhline(1, color="k", lw=0.8, ls=":", label="r²")
        a.legend(fontsize=8)
    a.set(xlabel="lag (h)", ylabel="MSRD / r²", title="mean squared relative displacement")
    a = ax[1, 1]
    steps, wall = s["steps"].diff(), s["wall_s"].diff()
    ms = 1e3 * wall / steps
    a.plot(h, ms.where(steps > 0), ".", ms=2, label="wall ms per step")
    a.set(xlabel="t (h)", ylabel="ms per step (wall)", title="cost and volume")
    a2 = a.twinx()
    a2.plot(h, 100 * s["volume_error_max"], color="C3", lw=0.8)
    a2.set_ylabel("largest cell volume error (%)", color="C3")
    fig.suptitle(f"job {info.id}: {spec['scene']['n_cells']} + {spec['scene']['n_cells']} cells, "
                 f"seed {info.seed}, {num['integrator']} Δt {num['dt_s']} s, "
                 f"ε_CG {num['cg_tol']} — {state} at t = {info.t_s / 3600:.1f} h", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "fusion.png", dpi=100)
    plt.close(fig)

    def at(hours):
        q = s.iloc[int((s["t_s"] - 3600 * hours).abs().argmin())]
        return q
    md = [f"# Job {info.id}: {state} at t = {info.t_s / 3600:.2f} h", "",
          "Generated by `docs/science/tools/fusion_day_report.py " + " ".join(sys.argv[1:]) + "`.", "",
          "| t (h) | θ (°) | shape index | unique contacts (norm.) | neck radius (µm) | "
          "largest volume error |", "|---|---|---|---|---|---|"]
    for hh in (0.5, 1, 2, 4, 6, 12, 18, 24):
        if 3600 * hh > s["t_s"].max() + 30:
            break
        q = at(hh)
        md.append(f"| {hh:g} | {q['theta_deg']:.1f} | {q['shape_index_mean']:.3f} | "
                  f"{q['unique_contacts_norm']:.2f} | {q['neck_radius_um']:.1f} | "
                  f"{100 * q['volume_error_max']:.2f} % |")
    late = s[s["t_s"] >= 6 * 3600]
    total_wall = float(s["wall_s"].iloc[-1]) if len(s) else math.nan
    md += ["", "| | |", "|---|---|",
           f"| steps | {info.steps} ({int(res.get('steps_rejected', 0))} rejected and redone; "
           f"smallest Δt {res.get('dt_min_s', math.nan):g} s) |",
           f"| wall time | {total_wall:.0f} s ({total_wall / 3600:.2f} h; "
           f"{1e3 * total_wall / max(info.steps, 1):.1f} ms per step, one thread, "
           "another job on the second core) |",
           f"| CG iterations per step | {res.get('cg_iters_mean', math.nan):.1f} |",
           f"| Eq. 1 | θ_eq {res.get('theta_eq_deg', math.nan):.1f} ± "
           f"{res.get('theta_eq_deg_se', math.nan):.1f}°, τ_f {res.get('tau_f_s', math.nan):.0f}"
           f" ± {res.get('tau_f_s_se', math.nan):.0f} s (ok: {res.get('eq1_ok', 0):g}) |"]
    if len(late):
        md.append(f"| θ from 6 h on | mean {late['theta_deg'].mean():.1f}°, SD "
                  f"{late['theta_deg'].std():.1f}°, range {late['theta_deg'].min():.1f}–"
                  f"{late['theta_deg'].max():.1f}° |")
    if len(msrd):
        md.append(f"| MSRD at the longest lag | {msrd['y'].iloc[-1] / r_cell ** 2:.2f} r² "
                  f"(lag {msrd['x'].iloc[-1] / 3600:.1f} h; r = {r_cell:.2f} µm, the cells' "
                  "mean radius) |")
    md.append(f"| mixing time | {res.get('mixing_time_s', math.nan):.0f} s (reached: "
              f"{res.get('mixing_reached', 0):g}) |")
    md.append(f"| cell volume error | largest over the samples "
              f"{100 * s['volume_error_max'].max():.2f} % (median "
              f"{100 * s['volume_error_max'].median():.2f} %), at the end "
              f"{100 * s['volume_error_max'].iloc[-1]:.2f} % |")
    if args.same_as:
        other = args.same_as
        b = c.job(other).samples()
        n, diff = same_bits(s, b)
        md += ["", f"**Same bits as {other}** (the same spec and seed, run for "
               f"{b['t_s'].max() / 3600:.1f} h): " + (
                   f"all {n} common samples equal, every column but the wall time." if diff is None
                   and n else f"differ at t = {diff[0]:.0f} s in {diff[1]} ({diff[2]!r} against "
                   f"{diff[3]!r}), after {n} common samples." if diff else "no common samples.")]
    (out / "summary.md").write_text("\n".join(md) + "\n")
    for f in ("job.txt", "spec.json", "results.txt", "samples.csv", "msrd.csv", "fusion.png", "summary.md"):
        print(out / f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
