#!/usr/bin/python3
"""The MSRD of neighbours (docs/model.md §8.6) as it is and with the aggregate's rigid turn taken
out, from the saved geometries in rotation/*.npz: the cells' centroids and contacting pairs at
each snapshot of day-long runs made before the engine reported `mixing_time_less_rotation_s`.
A run made today has the engine's own figures (`msrd_end_less_rotation_um2`,
`mixing_time_less_rotation_s`, `turn_end_deg`) and needs no file.

    docs/science/jam-day/less_rotation.py GEOMETRY.npz [--radius-um R] [--origins-from SECONDS]
                                          [--csv OUT.csv]

Between each origin o and o + lag every pair's relative vector at o is first turned by the
rotation that best carries all the cells' centroids at o onto those at o + lag (least squares
about the centroids: scipy's Rotation.align_vectors); a doublet that turns as a body moves every
pair's relative vector without any cell changing its neighbours. Prints, per lag, both curves,
the turn's share and the mean angle, and both mixing times (MSRD = r²).
"""
import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation


def load_geometry(path):
    """(r, times, centroids a snapshot, contacting pairs a snapshot) from a saved geometry."""
    g = np.load(path)
    bounds = np.concatenate([[0], np.cumsum(g["pair_counts"])])
    pairs_at = [g["pairs"][bounds[k]:bounds[k + 1]] for k in range(len(g["ts"]))]
    return float(g["r"]), np.asarray(g["ts"], float), np.asarray(g["xs"], float), pairs_at


def best_rotation(p, q):
    """The rotation (3 × 3, det +1) that best carries the points p onto q about their centroids."""
    rot, _ = Rotation.align_vectors(q - q.mean(axis=0), p - p.mean(axis=0))
    return rot.as_matrix()


def msrd_less_rotation(xs, pairs_at, first_origin=0):
    """Per lag (in samples): the summed squared relative displacements as they are and less the
    rotation, the pair counts, the summed rotation angles (degrees, one per origin) and the
    origin counts. Every origin–pair counts once (the engine's pooling); origins before sample
    first_origin are left out."""
    nl = len(xs)
    raw, less, angle = np.zeros(nl), np.zeros(nl), np.zeros(nl)
    counts, origins = np.zeros(nl, dtype=int), np.zeros(nl, dtype=int)
    for o in range(first_origin, nl):
        if len(pairs_at[o]) == 0:
            continue
        p = np.asarray(pairs_at[o])
        rel0 = xs[o, p[:, 0]] - xs[o, p[:, 1]]
        for lag in range(nl - o):
            rel = xs[o + lag, p[:, 0]] - xs[o + lag, p[:, 1]]
            rot = best_rotation(xs[o], xs[o + lag])
            raw[lag] += np.sum((rel - rel0) ** 2)
            less[lag] += np.sum((rel - rel0 @ rot.T) ** 2)
            angle[lag] += np.degrees(np.arccos(np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0)))
            counts[lag] += len(p)
            origins[lag] += 1
    return raw, less, counts, angle, origins


def mixing(lags, y):
    """The lag where y first reaches 1 (linear between samples), or None."""
    above = np.flatnonzero(y >= 1.0)
    if len(above) == 0:
        return None
    k = above[0]
    if k == 0:
        return 0.0
    return lags[k - 1] + (1.0 - y[k - 1]) / (y[k] - y[k - 1]) * (lags[k] - lags[k - 1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("geometry", type=Path, help="a saved geometry (rotation/*.npz)")
    ap.add_argument("--radius-um", type=float, default=None,
                    help="r for MSRD / r² (default: the one saved with the geometry)")
    ap.add_argument("--origins-from", type=float, default=0.0, metavar="SECONDS",
                    help="only time origins at or after this time (e.g. once the doublet has "
                         "fused: the MSRD without the fusion's own flow)")
    ap.add_argument("--csv", type=Path, default=None)
    args = ap.parse_args()

    try:
        r, ts, xs, pairs_at = load_geometry(args.geometry)
    except (OSError, KeyError, ValueError) as e:
        sys.exit(f"less_rotation: {args.geometry}: not a saved geometry ({e})")
    if args.radius_um is not None:
        r = args.radius_um
    if len(ts) < 3:
        sys.exit("less_rotation: fewer than 3 snapshots")
    dt = float(np.mean(np.diff(ts)))
    lags = np.arange(len(ts)) * dt
    first = int(np.searchsorted(ts, args.origins_from - 1e-9))
    if first >= len(ts) - 2:
        sys.exit(f"less_rotation: --origins-from {args.origins_from:g}: fewer than 3 snapshots "
                 f"from there")
    print(f"r = {r} µm, snapshots every {dt:.0f} s, {len(ts)} of them"
          + (f"; origins from t = {ts[first]:.0f} s ({len(ts) - first} of them)" if first else ""))

    raw, less, counts, angle, origins = msrd_less_rotation(xs, pairs_at, first)
    nl = len(ts) - first  # the lags some origin reaches
    has = counts > 0
    y_raw = np.where(has, raw / np.maximum(counts, 1), np.nan) / r**2
    y_less = np.where(has, less / np.maximum(counts, 1), np.nan) / r**2
    turn = np.where(origins > 0, angle / np.maximum(origins, 1), np.nan)
    print()
    print("| lag (s) | origins | MSRD / r² | less the rotation / r² | share of the rotation "
          "| turned (°, mean over origins) |")
    print("|---|---|---|---|---|---|")
    for k in sorted(set(np.round(np.geomspace(1, nl - 1, 14)).astype(int))):
        share = 1.0 - y_less[k] / y_raw[k] if y_raw[k] > 0 else float("nan")
        print(f"| {lags[k]:.0f} | {origins[k]} | {y_raw[k]:.3g} | {y_less[k]:.3g} | "
              f"{share:.0%} | {turn[k]:.1f} |")
    print()
    for name, y in (("as it is", y_raw), ("less the rotation", y_less)):
        mt = mixing(lags[:nl], y[:nl])
        print(f"mixing time, {name}: " + (f"{mt:.0f} s" if mt is not None
                                          else f"not reached in {lags[nl - 1]:.0f} s"))
    if args.csv:
        with open(args.csv, "w") as f:
            f.write("lag_s,origins,msrd_r2,msrd_less_rotation_r2,turned_deg\n")
            for k in range(nl):
                f.write(f"{lags[k]:.6g},{origins[k]},{y_raw[k]:.6g},{y_less[k]:.6g},"
                        f"{turn[k]:.6g}\n")


if __name__ == "__main__":
    main()
