#!/usr/bin/env python3
"""θ(t) of a fusion run with its Eq. 1 and Eq. 2 fits, as a PNG (gnuplot).

    docs/science/tools/plot_fusion.py RUN_DIR OUT.png [TITLE]

RUN_DIR is a foam-run output folder (samples.csv, summary.json). The fitted curves are drawn
from the parameters in summary.json; a fit that failed is named in the legend with its reason.
"""
import csv
import json
import math
import subprocess
import sys
import tempfile


def why(fit):
    return fit.get("why", "not run")[:70].replace("'", "")


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    run, png = sys.argv[1], sys.argv[2]
    title = sys.argv[3] if len(sys.argv) > 3 else "fusion angle"
    with open(f"{run}/samples.csv") as f:
        rows = list(csv.DictReader(f))
    with open(f"{run}/summary.json") as f:
        summary = json.load(f)
    data = [(float(r["t_s"]) / 60, float(r["theta_deg"])) for r in rows
            if r["theta_deg"] not in ("", "nan")]
    fits = summary.get("fits", {})
    script = [
        "set terminal pngcairo size 900,600 enhanced font 'DejaVu Sans,11'",
        f"set output '{png}'",
        f"set title '{title}'",
        "set xlabel 't (min)'",
        "set ylabel 'fusion angle θ (°)'",
        "set key bottom right",
        "set grid",
    ]
    plots = ["'$data' using 1:2 with points pt 7 ps 0.8 lc rgb '#1f77b4' title 'θ(t) (samples)'"]
    eq1 = fits.get("eq1", {})
    if eq1.get("ok"):
        p = eq1["parameters"]
        te, t0, tf = (p[k]["value"] for k in ("theta_eq_deg", "theta0_deg", "tau_f_s"))
        se = p["theta_eq_deg"]["std_error"]
        plots.append(f"{te} + ({t0} - {te}) * exp(-x * 60 / {tf}) lw 2 lc rgb '#d62728' "
                     f"title sprintf('Eq. 1: θ_{{eq}} = %.1f ± %.1f°, τ_f = %.0f s', {te}, {se}, {tf})")
    else:
        plots.append(f"NaN title 'Eq. 1 failed: {why(eq1)}' noenhanced")
    eq2 = fits.get("eq2", {})
    if eq2.get("ok"):
        p = eq2["parameters"]
        tg, teps, th0 = (p[k]["value"] for k in ("tau_gamma_s", "tau_eps_s", "theta0_deg"))
        k = teps / tg
        up, um = (-k + math.sqrt(k * k + 4)) / 2, (-k - math.sqrt(k * k + 4)) / 2
        lam = 0.5 * math.sqrt(1 / tg**2 + 4 / teps**2)
        u0 = math.cos(math.radians(th0))
        c = (u0 - up) / (u0 - um)
        script.append(f"u(t) = ({up} - ({um}) * {c} * exp(-{lam} * t)) / (1 - {c} * exp(-{lam} * t))")
        plots.append(f"acos(u(x * 60)) * 180 / pi lw 2 dt 2 lc rgb '#2ca02c' "
                     f"title sprintf('Eq. 2: τ_Γ = %.0f s, τ_ε = %.0f s', {tg}, {teps})")
    else:
        plots.append(f"NaN title 'Eq. 2 failed: {why(eq2)}' noenhanced")
    script.append("$data << EOD")
    script += [f"{t} {th}" for t, th in data]
    script.append("EOD")
    script.append("plot [0:] " + ", \\\n  ".join(plots))
    with tempfile.NamedTemporaryFile("w", suffix=".gp", delete=False) as f:
        f.write("\n".join(script) + "\n")
        path = f.name
    subprocess.run(["gnuplot", path], check=True)


if __name__ == "__main__":
    main()
