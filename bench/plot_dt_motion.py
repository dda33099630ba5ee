#!/usr/bin/env python3
"""Summarises study_dt_motion's CSV files: per configuration, the MSRD at a time T and its ratio
to a reference configuration's (the same seed), the fit M(Δt) = M₀ / (1 + a Δt) through the
contact-implicit rows, and a PNG of MSRD(t) per configuration and of MSRD(T) against Δt.

    bench/plot_dt_motion.py OUT.png T_s REFERENCE_CONFIG SEED_FILES [SEED_FILES ...]

SEED_FILES is one seed's CSV file, or several joined by '+' (the same seed's runs; a config
present in more than one keeps its first file's rows). REFERENCE_CONFIG names the row every ratio
divides by (e.g. ros2:0.1:block-jacobi:1e-3). Prints a Markdown table.
"""
import csv
import math
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def load(paths):
    runs = defaultdict(list)  # config -> [(t, msrd, unique, rms, wall)]
    for path in paths.split("+"):
        here = defaultdict(list)
        with open(path) as f:
            for row in csv.DictReader(f):
                here[row["config"]].append(
                    (float(row["t_s"]), float(row["msrd_um2"]), float(row["unique_contacts"]),
                     float(row["rms_from_first_um"]), float(row["wall_s"])))
        for config, series in here.items():
            runs.setdefault(config, series)
    return runs


def at(series, t):
    for row in series:
        if abs(row[0] - t) < 1e-6:
            return row
    return None


def fit(points):
    """Least squares of 1/M = (1 + a Δt)/M₀ in Δt: linear in Δt."""
    n = len(points)
    if n < 2:
        return None
    xs = [d for d, _ in points]
    ys = [1 / m for _, m in points]
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx
    inter = my - slope * mx
    return 1 / inter, slope / inter  # M₀, a


def main():
    if len(sys.argv) < 5:
        print(__doc__)
        return 2
    out, t_end, ref = sys.argv[1], float(sys.argv[2]), sys.argv[3]
    files = sys.argv[4:]
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.8))
    print(f"| seed file | configuration | MSRD({t_end:g} s) (µm²) | / reference | unique contacts "
          f"| RMS distance from the file's first row (µm) | wall (s) |")
    print("|---|---|---|---|---|---|---|")
    for k, path in enumerate(files):
        runs = load(path)
        if ref not in runs or at(runs[ref], t_end) is None:
            print(f"{path}: no {ref} row at t = {t_end:g}", file=sys.stderr)
            return 1
        m_ref = at(runs[ref], t_end)[1]
        ci = []
        for config, series in runs.items():
            row = at(series, t_end)
            if row is None:
                continue
            scheme, dt = config.split(":")[0], float(config.split(":")[1])
            print(f"| {path.split('+')[0].rsplit('/', 1)[-1]} | {config} | {row[1]:.2f} | {row[1] / m_ref:.2f} "
                  f"| {row[2]:.3f} | {row[3]:.2f} | {row[4]:.0f} |")
            if scheme == "contact-implicit" and config.endswith(":1e-3"):
                ci.append((dt, row[1]))
            if k == 0:
                ts = [r[0] for r in series]
                ms = [r[1] for r in series]
                left.plot(ts, ms, label=config.replace(":block-jacobi", ""))
            marker = {"contact-implicit": "o", "ros2": "s", "semi-implicit": "^",
                      "contact-implicit-consistent": "D"}.get(scheme, "x")
            colour = {"contact-implicit": "C0", "ros2": "C3", "semi-implicit": "C2",
                      "contact-implicit-consistent": "C1"}.get(scheme, "C7")
            right.scatter([dt], [row[1] / m_ref], marker=marker, color=colour,
                          label=scheme if k == 0 else None)
        f = fit(ci)
        if f:
            m0, a = f
            print(f"\n{path}: contact-implicit fit M(Δt) = M₀/(1 + a Δt): M₀ = {m0:.2f} µm² "
                  f"({m0 / m_ref:.2f} × reference), a = {a:.2f} /s\n")
            xs = [10 ** (e / 20) for e in range(-40, 1)]
            right.plot(xs, [m0 / (1 + a * x) / m_ref for x in xs], color="C0", lw=0.8,
                       ls="--" if k else "-")
    handles, labels = right.get_legend_handles_labels()
    uniq = dict(zip(labels, handles))
    right.legend(uniq.values(), uniq.keys())
    right.set_xscale("log")
    right.set_xlabel("Δt (s)")
    right.set_ylabel(f"MSRD({t_end:g} s) / {ref.split(':')[0]} Δt {ref.split(':')[1]} s")
    right.axhline(1, color="grey", lw=0.5)
    right.set_title("motion against Δt (each seed its own reference)")
    left.set_xlabel("t (s)")
    left.set_ylabel("MSRD from t = 0 (µm²)")
    left.set_title(files[0].split("+")[0].rsplit("/", 1)[-1])
    left.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
