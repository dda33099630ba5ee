#!/usr/bin/env python3
"""A long run's cost window by window, from its samples.csv: whether late hours cost what early
ones do (junctions grow, contacts change).

  bench/hourly_cost.py RUN/samples.csv [--every 3600] [--from SECONDS]

One markdown row a window of EVERY simulated seconds (the last one may be shorter): steps, ms a
step and minutes of wall time a simulated hour (from samples.csv's wall_s, which a resumed run
carries over from its earlier processes), CG iterations a step and, where the spec sampled them,
the active contact pairs (means over the window's samples, each weighted by its steps). --from
starts the first window at that sample time: after a resume, the first sample's wall_s holds the
process's loading and setup, so start past it to time steps only.
"""
import argparse
import csv
import sys


def read_samples(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{path}: no samples")
    for k in ("t_s", "steps", "wall_s", "cg_iters_mean"):
        if k not in rows[0]:
            raise ValueError(f"{path}: no column {k!r}")
    return [{k: float(v) for k, v in r.items() if v not in ("", None)} for r in rows]


def windows(rows, every, start=0.0):
    """(t0, t1, steps, wall_s, CG iterations a step, contact pairs or None) per window: from the
    last sample at or before each window's start to the last one inside it."""
    rows = [r for r in rows if r["t_s"] >= start - 1e-9]
    if len(rows) < 2:
        return []
    out = []
    first = rows[0]
    edge = first["t_s"] + every
    window = []
    for r in rows[1:]:
        window.append(r)
        if r["t_s"] >= edge - 1e-9 or r is rows[-1]:
            steps = r["steps"] - first["steps"]
            if steps > 0:
                weights = []
                prev = first["steps"]
                for w in window:
                    weights.append(w["steps"] - prev)
                    prev = w["steps"]
                total = sum(weights)
                cg = sum(w["cg_iters_mean"] * n for w, n in zip(window, weights)) / total
                pairs = None
                if all("contact_pairs" in w for w in window):
                    pairs = sum(w["contact_pairs"] * n for w, n in zip(window, weights)) / total
                out.append((first["t_s"], r["t_s"], steps, r["wall_s"] - first["wall_s"], cg, pairs))
            first = r
            window = []
            edge = r["t_s"] + every
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("samples")
    ap.add_argument("--every", type=float, default=3600.0, help="simulated seconds a window")
    ap.add_argument("--from", dest="start", type=float, default=0.0, metavar="SECONDS")
    a = ap.parse_args()
    if not a.every > 0:
        sys.exit("hourly_cost: --every must be > 0 s")
    try:
        rows = read_samples(a.samples)
    except (OSError, ValueError) as e:
        sys.exit(f"hourly_cost: {e}")
    ws = windows(rows, a.every, a.start)
    if not ws:
        sys.exit(f"hourly_cost: {a.samples}: fewer than two samples from t = {a.start:g} s")
    print("| simulated window | steps | ms a step | min a simulated hour | CG iterations a step "
          "| contact pairs |")
    print("|---|---|---|---|---|---|")
    for t0, t1, steps, wall, cg, pairs in ws:
        print(f"| {t0 / 3600:.2f}–{t1 / 3600:.2f} h | {steps:.0f} | {1000 * wall / steps:.0f} | "
              f"{wall / (t1 - t0) * 60:.1f} | {cg:.1f} | "
              + ("—" if pairs is None else f"{pairs:.0f}") + " |")


if __name__ == "__main__":
    main()
