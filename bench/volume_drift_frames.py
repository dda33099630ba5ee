#!/usr/bin/env python3
"""What happened step by step before a run failed: reads the frames that
bench/study_volume_drift writes (OUT_DIR/frame_T.bin, one per step from frames_from_s on)
and prints, for each step, the fastest vertices by cell, the largest vertex forces, and the
contact pairs read deepest: their mean gap along the bisector, area, n_A.n_B, the triangles'
true distance (0 when they cross) and k |gap| area, the force the law puts on the pair.

    bench/volume_drift_frames.py OUT_DIR [--k 71.1] [--pairs 4] [--cells A,B]

With --cells only pairs between those two cells are listed.
"""
import argparse
import glob
import os
import sys

import numpy as np

PAIR = np.dtype([("ta", "<i4"), ("tb", "<i4"), ("area", "<f8"), ("gap", "<f8")])


def load(path):
    b = open(path, "rb").read()
    nv, nt = (int(n) for n in np.frombuffer(b[:8], np.int32))
    o = 8

    def take(dtype, count, shape=None):
        nonlocal o
        a = np.frombuffer(b, dtype, count, o)
        o += a.nbytes
        return a.reshape(shape) if shape else a

    f = {"x": take(np.float64, 3 * nv, (nv, 3)), "v": take(np.float64, 3 * nv, (nv, 3))}
    f["tri"] = take(np.int32, 3 * nt, (nt, 3))
    f["tri_cell"] = take(np.int32, nt)
    f["vertex_cell"] = take(np.int32, nv)
    f["force"] = take(np.float64, 3 * nv, (nv, 3))
    n_pairs = int(take(np.int32, 1)[0])
    f["pairs"] = take(PAIR, n_pairs)
    return f


def closest_on_triangle(p, a, b, c):
    """Ericson's closest point of triangle abc to p."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = ab @ ap, ac @ ap
    if d1 <= 0 and d2 <= 0:
        return a
    bp = p - b
    d3, d4 = ab @ bp, ac @ bp
    if d3 >= 0 and d4 <= d3:
        return b
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        return a + ab * (d1 / (d1 - d3))
    cp = p - c
    d5, d6 = ab @ cp, ac @ cp
    if d6 >= 0 and d5 <= d6:
        return c
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        return a + ac * (d2 / (d2 - d6))
    va = d3 * d6 - d5 * d4
    if va <= 0 and d4 - d3 >= 0 and d5 - d6 >= 0:
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))
    den = 1 / (va + vb + vc)
    return a + ab * vb * den + ac * vc * den


def segment_distance(p0, p1, q0, q1):
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, f, c, b = d1 @ d1, d2 @ d2, d2 @ r, d1 @ r, d1 @ d2
    den = a * e - b * b
    s = np.clip((b * f - c * e) / den, 0, 1) if den > 1e-300 else 0.0
    t = (b * s + f) / e if e > 0 else 0.0
    if t < 0:
        t, s = 0.0, (np.clip(-c / a, 0, 1) if a > 0 else 0.0)
    elif t > 1:
        t, s = 1.0, (np.clip((b - c) / a, 0, 1) if a > 0 else 0.0)
    return float(np.linalg.norm(p0 + s * d1 - (q0 + t * d2)))


def crosses(p0, p1, t):
    n = np.cross(t[1] - t[0], t[2] - t[0])
    d0, d1 = n @ (p0 - t[0]), n @ (p1 - t[0])
    if d0 * d1 > 0 or d0 == d1:
        return False
    x = p0 + d0 / (d0 - d1) * (p1 - p0)
    return all(n @ np.cross(t[(k + 1) % 3] - t[k], x - t[k]) >= 0 for k in range(3))


def triangle_distance(a, b):
    """As study_volume_drift's: 0 when an edge of one crosses the other."""
    if any(crosses(a[i], a[(i + 1) % 3], b) or crosses(b[i], b[(i + 1) % 3], a)
           for i in range(3)):
        return 0.0
    d = min(min(np.linalg.norm(p - closest_on_triangle(p, *q)) for p in s)
            for s, q in ((a, b), (b, a)))
    return min(d, min(segment_distance(a[i], a[(i + 1) % 3], b[j], b[(j + 1) % 3])
                      for i in range(3) for j in range(3)))


def unit_normal(x, t):
    n = np.cross(x[t[1]] - x[t[0]], x[t[2]] - x[t[0]])
    return n / np.linalg.norm(n)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out_dir")
    ap.add_argument("--k", type=float, default=71.1, help="cells.k_contact, nN/µm³")
    ap.add_argument("--pairs", type=int, default=4)
    ap.add_argument("--cells", default="")
    a = ap.parse_args()
    files = sorted(glob.glob(os.path.join(a.out_dir, "frame_*.bin")),
                   key=lambda p: float(os.path.basename(p)[6:-4]))
    if not files:
        sys.exit(f"{a.out_dir}: no frame_*.bin (run study_volume_drift with frames_from_s)")
    only = {int(c) for c in a.cells.split(",")} if a.cells else None
    for path in files:
        t = float(os.path.basename(path)[6:-4])
        f = load(path)
        x, tri, tc, vc, pairs = f["x"], f["tri"], f["tri_cell"], f["vertex_cell"], f["pairs"]
        speed = np.linalg.norm(f["v"], axis=1)
        force = np.linalg.norm(f["force"], axis=1)
        fast = {int(c): float(speed[vc == c].max()) for c in np.unique(vc)}
        fast = sorted(fast.items(), key=lambda kv: -kv[1])[:4]
        top = np.argsort(-force)[:4]
        print(f"t = {t:.4f} s: |v| max by cell (µm/s) "
              + ", ".join(f"{c}: {s:.3f}" for c, s in fast)
              + f"; median |v| {np.median(speed):.4f}; |F| largest (nN) "
              + ", ".join(f"{force[i]:.2f} (cell {vc[i]})" for i in top)
              + f", median {np.median(force):.3f}")
        sel = np.arange(len(pairs))
        if only:
            sel = np.array([i for i in sel if {tc[pairs["ta"][i]], tc[pairs["tb"][i]]} == only],
                           dtype=int)
        for i in sel[np.argsort(pairs["gap"][sel])][:a.pairs]:
            ta, tb = int(pairs["ta"][i]), int(pairs["tb"][i])
            gap, area = float(pairs["gap"][i]), float(pairs["area"][i])
            dot = unit_normal(x, tri[ta]) @ unit_normal(x, tri[tb])
            dist = triangle_distance(x[tri[ta]], x[tri[tb]])
            print(f"    pair {ta}-{tb} (cells {tc[ta]}-{tc[tb]}): gap {gap:+.3f} µm over "
                  f"{area:.3f} µm², n_A.n_B {dot:+.3f}, triangles {dist:.3f} µm apart, "
                  f"k|gap|area {a.k * abs(gap) * area:.1f} nN")


if __name__ == "__main__":
    main()
