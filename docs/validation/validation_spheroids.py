#!/usr/bin/env python3
"""Tables of docs/validation.md's spheroid section from docs/validation/validation_spheroids.sh's runs.

    python3 docs/validation/validation_spheroids.py OUT [--dat docs/validation]

Each run's surface contact angle is averaged over its last 2000 s, or the second half of a
shorter run (the aggregates have settled by then: see the time courses printed with --series).
Runs without summary.json are skipped. A run's step is its folder's label: dt0.5 the one-spring
contact-implicit step at Δt 0.5 s, ε_CG 1e-2; dt0.1 the same at Δt 0.1 s, ε_CG 1e-3."""
import argparse, csv, glob, json, math, os, re, statistics

ap = argparse.ArgumentParser()
ap.add_argument("out")
ap.add_argument("--dat", help="write spheroids-*.dat for docs/validation/plot.gp here")
ap.add_argument("--series", action="store_true", help="print each run's angle every 500 s")
args = ap.parse_args()

runs = []
for d in sorted(glob.glob(os.path.join(args.out, "n*-a*-s*-*-pa*"))):
    m = re.match(r"n(\d+)-a([\d.]+)-s(\d+)-([\w.]+)-pa([\d.]+)$", os.path.basename(d))
    if not m or not os.path.exists(os.path.join(d, "summary.json")):
        continue
    rows = list(csv.DictReader(open(os.path.join(d, "samples.csv"))))
    t = [float(r["t_s"]) for r in rows]
    th = [float(r["surface_contact_angle_deg"]) for r in rows]
    window = min(2000, t[-1] / 2)  # the last 2000 s, or the second half of a shorter run
    last = [v for tt, v in zip(t, th) if tt > t[-1] - window and not math.isnan(v)]
    n, a, s, step, pa = int(m[1]), float(m[2]), int(m[3]), m[4], float(m[5])
    runs.append(dict(n=n, alpha=a, seed=s, step=step, pa=pa, t_end=t[-1],
                     theta=statistics.mean(last), sd=statistics.pstdev(last), t=t, th=th,
                     wall=json.load(open(os.path.join(d, "summary.json")))["wall_s"]))

def acos_deg(a):
    return math.degrees(math.acos(a))

print("| N | α | seed | step | p_a (kPa) | run | θ_c, last 2000 s (sd in time) | arccos α | difference |")
print("|---|---|---|---|---|---|---|---|---|")
for r in runs:
    print(f"| {r['n']} | {r['alpha']} | {r['seed']} | {r['step']} | {r['pa']} | {r['t_end']:.0f} s "
          f"| {r['theta']:.2f}° (±{r['sd']:.2f}) | {acos_deg(r['alpha']):.2f}° "
          f"| {r['theta'] - acos_deg(r['alpha']):+.2f}° |")
    if args.series:
        print("    " + " ".join(f"{tt:.0f}:{v:.1f}" for tt, v in zip(r["t"], r["th"]) if tt % 500 == 0))

motile = {}
for r in runs:
    if r["step"] == "dt0.5" and r["pa"] == 0.0372:
        motile.setdefault(r["alpha"], []).append(r["theta"])
print("\nMotile (p_a 0.0372 kPa, Δt 0.5 s), over N and seeds:")
print("| α | arccos α | runs | θ_c mean ± sd | difference (min … max) |")
print("|---|---|---|---|---|")
for a, v in sorted(motile.items()):
    d = [x - acos_deg(a) for x in v]
    sd = statistics.stdev(v) if len(v) > 1 else 0
    print(f"| {a} | {acos_deg(a):.2f}° | {len(v)} | {statistics.mean(v):.2f}° ± {sd:.2f} "
          f"| {statistics.mean(d):+.2f}° ({min(d):+.2f} … {max(d):+.2f}) |")

if args.dat:
    with open(os.path.join(args.dat, "spheroids-passive.dat"), "w") as f:
        f.write("# Passive spheroids (p_a 0), N = 20, seed 1, Δt 0.5 s: surface contact angle over the\n"
                "# last 2000 s of 4000 s (docs/validation.md; docs/validation/validation_spheroids.py)\n# alpha theta_c\n")
        for r in runs:
            if r["pa"] == 0 and r["step"] == "dt0.5" and r["n"] == 20:
                f.write(f"{r['alpha']} {r['theta']:.2f}\n")
    with open(os.path.join(args.dat, "spheroids-motile.dat"), "w") as f:
        f.write("# Motile spheroids (p_a 0.0372 kPa), N = 20 and 30, seeds 1-3, Δt 0.5 s: mean and sd over\n"
                "# runs of the surface contact angle over the last 2000 s of 6000 s\n# alpha mean sd\n")
        for a, v in sorted(motile.items()):
            if a in (0.3, 0.6, 0.9):
                f.write(f"{a} {statistics.mean(v):.2f} {statistics.stdev(v):.2f}\n")
