#!/usr/bin/env python3
"""θ(t) RMS error against cost of a study (the doublet study's doublet.csv or
fusion_accuracy.py's fusion.csv), one point per configuration, the Pareto front drawn
through the configurations no other beats on both (PNG, gnuplot).

    docs/study/plot_study.py STUDY.csv OUT.png [TITLE]

Errors below 0.01° are drawn at 0.01° (log scale); failed runs are left out and listed in the
title.
"""
import csv
import subprocess
import sys
import tempfile

COLOURS = {"standard": "#000000", "preset": "#000000", "dt": "#1f77b4", "mesh": "#d62728", "cg_tol": "#2ca02c",
           "preconditioner": "#9467bd", "quadrature": "#8c564b", "remesh": "#e377c2",
           "integrator": "#ff7f0e", "combined": "#7f7f7f", "k_AB": "#17becf", "draft": "#000000"}


def label(r):
    k = r["knob"]
    if k == "preset":  # the fusion study's rows: draft, standard
        return r["name"]
    if k == "dt":
        return f"Δt {r['dt_s']}"
    if k == "mesh":  # the fusion study's mesh rows at another Δt say so in their name
        return f"{r['triangles']} tri" + (f", Δt {r['dt_s']}" if "-dt-" in r.get("name", "") else "")
    if k == "cg_tol":
        return f"ε {r['cg_tol']}"
    if k == "preconditioner":
        return r["preconditioner"]
    if k == "quadrature":
        return r["quadrature"]
    if k == "remesh":
        return f"τ_r ×{r['remesh_factor']}"
    if k == "integrator":
        short = {"semi-implicit": "semi", "contact-implicit": "CI"}.get(r["integrator"], r["integrator"])
        fine = f", {r['triangles']} tri" if r.get("triangles", "320") != "320" else ""
        return f"{short} Δt {r['dt_s']}{fine}"
    if k == "k_AB":
        f = float(r["k_factor"])
        name = f"k_AB ×{f:g}" if f >= 0.2 else f"k_AB ×1/{round(1 / f)}"
        return f"{name}, Δt {r['dt_s']}"
    if k == "draft":
        return "draft"
    if k == "combined":
        return f"{r['triangles']}/{r['dt_s']}/{r['cg_tol']}"
    return k


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    src, png = sys.argv[1], sys.argv[2]
    title = sys.argv[3] if len(sys.argv) > 3 else "doublet: error against cost"
    with open(src) as f:
        rows = [r for r in csv.DictReader(f) if r["knob"] != "reference"]
    failed = {}
    for r in rows:
        if r["outcome"] != "ok":
            failed.setdefault(r["outcome"], []).append(label(r))
    ok = [r for r in rows if r["outcome"] == "ok"]
    with tempfile.TemporaryDirectory() as tmp:
        blocks, plots = [], []
        for knob, colour in COLOURS.items():
            pts = [r for r in ok if r["knob"] == knob]
            if not pts:
                continue
            name = f"{tmp}/{knob}.dat"
            with open(name, "w") as out:
                for r in pts:
                    err = max(float(r["trajectory_rms_deg"]), 0.01)
                    out.write(f"{float(r['wall_per_sim_hour_s'])} {err} \"{label(r)}\"\n")
            plots.append(f"'{name}' using 1:2 with points pt 7 ps 1.2 lc rgb '{colour}' "
                         f"title '{knob}' noenhanced")
            plots.append(f"'{name}' using 1:2:3 with labels offset 0.6,0.6 left font ',8' "
                         f"tc rgb '{colour}' notitle")
        front = sorted((r for r in ok if r["pareto"] == "1"),
                       key=lambda r: float(r["wall_per_sim_hour_s"]))
        fname = f"{tmp}/front.dat"
        with open(fname, "w") as out:
            for r in front:
                out.write(f"{float(r['wall_per_sim_hour_s'])} "
                          f"{max(float(r['trajectory_rms_deg']), 0.01)}\n")
        if front:
            plots.insert(0, f"'{fname}' using 1:2 with steps lw 2 dt 2 lc rgb '#444444' "
                            f"title 'Pareto front' noenhanced")
        subtitle = "".join(f"\\n{kind}: " + ", ".join(names) for kind, names in failed.items())
        title = title.replace('"', "'")
        script = [
            "set terminal pngcairo size 1100,700 enhanced font 'DejaVu Sans,11'",
            f"set output '{png}'",
            f'set title "{title}{subtitle}" noenhanced',
            "set xlabel 'wall time per simulated hour (s, one core)'",
            "set ylabel 'RMS error of the angle trajectory against the reference (°)'",
            "set logscale xy",
            "set grid",
            "set key outside right top",
            "plot " + ", \\\n     ".join(plots),
        ]
        with open(f"{tmp}/plot.gp", "w") as out:
            out.write("\n".join(script) + "\n")
        subprocess.run(["gnuplot", f"{tmp}/plot.gp"], check=True)


if __name__ == "__main__":
    main()
