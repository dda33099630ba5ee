#!/usr/bin/env python3
"""The stability map as a chart (PNG, gnuplot): one panel per integrator and step kind (fixed or
adaptive Δt), every run of
study_stability_map's stability-map.csv as a point at (k_AB factor, Δt), its marker the outcome
(stable, or the failure kind that ended it), the largest stable Δt per motility joined by a line.

    docs/study/plot_stability_map.py stability-map.csv OUT.png

Within each k_AB group the three motilities p_a r/2γ = 0, 0.33, 1 sit left to right.
"""
import csv
import subprocess
import sys
import tempfile

# outcome → (point type, colour); unknown kinds get a default.
STYLE = {
    "stable": (7, "#2ca02c"),
    "contact-oscillation": (2, "#d62728"),
    "inverted-triangle": (9, "#ff7f0e"),
    "volume-drift": (5, "#9467bd"),
    "cg-not-converged": (13, "#8c564b"),
    "non-finite": (3, "#000000"),
    "interpenetration": (11, "#e377c2"),
    "separated": (6, "#7f7f7f"),
}
MOTILITY_OFFSET = [0.8, 1.0, 1.25]  # multiplies k_AB on the log axis
MOTILITY_DASH = [1, 2, 3]


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    src, png = sys.argv[1], sys.argv[2]
    with open(src) as f:
        rows = list(csv.DictReader(f))
    for r in rows:  # maps before the adaptive ladders had fixed steps only
        r.setdefault("adaptive", "0")
    panels = list(dict.fromkeys((r["integrator"], r["adaptive"]) for r in rows))
    motilities = sorted({float(r["pa_reduced"]) for r in rows})
    if len(motilities) > len(MOTILITY_OFFSET):
        sys.exit("plot_stability_map.py: more motilities than offsets")

    def x_of(r):
        return float(r["k_factor"]) * MOTILITY_OFFSET[motilities.index(float(r["pa_reduced"]))]

    with tempfile.TemporaryDirectory() as tmp:
        script = [
            # ~480 px a column: the axis labels of neighbouring panels must not overlap.
            f"set terminal pngcairo size {max(1500, 480 * ((len(panels) + 1) // 2))},1100 "
            "enhanced font 'DejaVu Sans,11'",
            f"set output '{png}'",
            f"set multiplot layout 2,{(len(panels) + 1) // 2} title 'Stability map of the doublet (200 s per run): "
            "outcome of every run, largest stable Δt per motility joined' noenhanced",
            "set logscale xy",
            "set xrange [0.01:6]",
            "set xtics ('1/64' 0.015625, '1/16' 0.0625, '1/4' 0.25, '1' 1, '4' 4)",
            "set xlabel 'k_AB × 71.1 nN/µm³ (p_a r/2γ = 0, 0.33, 1 left to right)' noenhanced",
            "set ylabel 'Δt (s)'",
            "set grid",
            "set key below maxrows 4 font ',9' noenhanced",
        ]
        for integ, adaptive in panels:
            mine = [r for r in rows if r["integrator"] == integ and r["adaptive"] == adaptive]
            tag = f"{integ}-{adaptive}"
            plots = []
            for outcome in dict.fromkeys(r["outcome"] for r in mine):
                name = f"{tmp}/{tag}-{outcome}.dat"
                with open(name, "w") as out:
                    for r in mine:
                        if r["outcome"] == outcome:
                            out.write(f"{x_of(r)} {float(r['dt_s'])}\n")
                pt, colour = STYLE.get(outcome, (1, "#17becf"))
                plots.append(f"'{name}' using 1:2 with points pt {pt} ps 1.5 lc rgb '{colour}' "
                             f"title '{outcome}'")
            for i, pa in enumerate(motilities):
                name = f"{tmp}/{tag}-limit-{i}.dat"
                with open(name, "w") as out:
                    for k in sorted({float(r["k_factor"]) for r in mine}):
                        rungs = sorted((float(r["dt_s"]), r["outcome"]) for r in mine
                                       if float(r["k_factor"]) == k
                                       and float(r["pa_reduced"]) == pa)
                        best = None
                        for dt, outcome in rungs:  # largest Δt below which every rung is stable
                            if outcome != "stable":
                                break
                            best = dt
                        if best is not None:
                            out.write(f"{k * MOTILITY_OFFSET[i]} {best}\n")
                plots.append(f"'{name}' using 1:2 with lines lw 1.5 dt {MOTILITY_DASH[i]} "
                             f"lc rgb '#444444' title 'largest stable, p_a r/2γ = {pa:g}'")
            kind = "adaptive Δt (stable = finished)" if adaptive == "1" else "fixed Δt"
            script.append(f"set title '{integ}, {kind}' noenhanced")
            script.append("plot " + ", \\\n     ".join(plots))
        script.append("unset multiplot")
        with open(f"{tmp}/plot.gp", "w") as out:
            out.write("\n".join(script) + "\n")
        subprocess.run(["gnuplot", f"{tmp}/plot.gp"], check=True)


if __name__ == "__main__":
    main()
