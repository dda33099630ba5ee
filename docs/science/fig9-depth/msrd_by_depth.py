#!/usr/bin/python3
"""Whose motion makes the MSRD: cells under the doublet's surface or cells on it? The MSRD of
neighbours (docs/model.md §8.6: pairs in contact at the origin, pooled over origins) split by where
the pair's cells are at the origin — both buried (no free surface), both on the surface, or
one of each — from a run's snapshots (foam-run with snapshot_every_s > 0).

    docs/science/fig9-depth/msrd_by_depth.py SNAPSHOT_DIR [--radius-um R] [--free-below F] [--touch-um D]
                           [--engine-summary summary.json] [--csv OUT.csv] [--layers]
                           [--less-rotation]

The snapshots carry meshes, not the engine's contact list, so contact is read from geometry:
a vertex of cell i touches cell j when it lies within D of j's surface (default 0.5 µm, a
point–triangle distance; the adhesion's range h0 is ~0.06 µm, the contact's overlap up to
~1 µm); i and j are in contact when at least 3 of either's vertices touch the other; a cell's free fraction is the share of its vertices that
touch no cell, and it is buried below F (default 0.05). --engine-summary compares the proxy's
all-pairs curve with the engine's own MSRD (the run's summary.json): the proxy is read only
where the two agree. Prints, per lag, the MSRD / r² of each class with its pair count, and
the mixing time (MSRD = r²) of each class. --less-rotation prints instead all pairs' MSRD as it
is and with the aggregate's rigid rotation between origin and lag taken out (a doublet that
turns as a body moves every pair's relative vector without any cell changing its neighbours).
"""
import argparse
import json
import pickle
import re
import sys
from pathlib import Path

import numpy as np


def data_array(text, name):
    m = re.search(r'<DataArray[^>]*Name="' + name + r'"[^>]*>(.*?)</DataArray>', text, re.S)
    if not m:
        raise ValueError(f"no DataArray {name!r}")
    return np.array(m.group(1).split(), dtype=float)


def read_snapshot(path):
    text = Path(path).read_text()
    t = float(data_array(text, "TIME")[0])
    pts = data_array(text, "Points").reshape(-1, 3)
    vcell = data_array(text, "cell_id").astype(int)  # the PointData one comes first
    tri = data_array(text, "connectivity").astype(int).reshape(-1, 3)
    return t, pts, vcell[: len(pts)], tri


def centroids(pts, vcell, tri, n):
    """Volume centroids: signed tetrahedra from each cell's vertex mean."""
    o = np.zeros((n, 3))
    np.add.at(o, vcell, pts)
    o /= np.bincount(vcell, minlength=n)[:, None]
    c = vcell[tri[:, 0]]
    a, b, d = (pts[tri[:, k]] - o[c] for k in range(3))
    vol = np.einsum("ij,ij->i", a, np.cross(b, d)) / 6.0
    w = np.zeros(n)
    np.add.at(w, c, vol)
    m = np.zeros((n, 3))
    np.add.at(m, c, vol[:, None] * (a + b + d) / 4.0)
    return o + m / w[:, None]


def point_triangle_distance(p, a, b, c):
    """Distances (m, t) from points p (m, 3) to triangles (a, b, c) (t, 3 each)."""
    n = np.cross(b - a, c - a)
    nn = np.linalg.norm(n, axis=1)
    n = n / np.where(nn > 0, nn, 1.0)[:, None]
    d = p[:, None, :] - a[None, :, :]
    h = np.einsum("mtk,tk->mt", d, n)
    q = p[:, None, :] - h[:, :, None] * n[None, :, :]  # projections on the planes

    def inside(u, v, w):
        return np.einsum("mtk,tk->mt", np.cross(v - u, q - u[None]), n) >= 0

    ins = inside(a, b, c) & inside(b, c, a) & inside(c, a, b)

    def seg(u, v):
        e = v - u
        s = np.clip(np.einsum("mtk,tk->mt", p[:, None, :] - u[None], e)
                    / np.maximum(np.einsum("tk,tk->t", e, e), 1e-300), 0.0, 1.0)
        return np.linalg.norm(p[:, None, :] - (u[None] + s[:, :, None] * e[None]), axis=2)

    edge = np.minimum(np.minimum(seg(a, b), seg(b, c)), seg(c, a))
    return np.where(ins, np.abs(h), edge)


def contacts(pts, vcell, tri, x, n, touch_um, reach_um):
    """Contacting cell pairs and each cell's free fraction: a vertex touches cell j when it
    lies within touch_um of j's surface (a point–triangle distance)."""
    verts = [np.flatnonzero(vcell == c) for c in range(n)]
    tris = [tri[vcell[tri[:, 0]] == c] for c in range(n)]
    touched = np.zeros(len(pts), dtype=bool)
    pairs = []
    for i in range(n):
        for j in range(i + 1, n):
            if np.linalg.norm(x[i] - x[j]) > reach_um:
                continue
            counts = []
            for u, w in ((i, j), (j, i)):
                p = pts[verts[u]]
                t = tris[w]
                lo = pts[verts[w]].min(axis=0) - touch_um
                hi = pts[verts[w]].max(axis=0) + touch_um
                near = np.all((p >= lo) & (p <= hi), axis=1)
                if not near.any():
                    counts.append(0)
                    continue
                d = point_triangle_distance(p[near], pts[t[:, 0]], pts[t[:, 1]], pts[t[:, 2]])
                hit = verts[u][near][d.min(axis=1) < touch_um]
                touched[hit] = True
                counts.append(len(hit))
            if max(counts) >= 3:
                pairs.append((i, j))
    free = np.array([1.0 - touched[v].mean() for v in verts])
    return pairs, free


CLASSES = ("all", "buried-buried", "buried-surface", "surface-surface")


LAYERS = ("all", "depth-0", "depth-1", "depth-2+")


def depths(pairs, free, free_below):
    """Each cell's depth in the contact graph: 0 on the surface (free fraction ≥ free_below), 1
    buried next to a surface cell, 2 buried with buried neighbours only, and so on (cells with
    no path to the surface: the largest depth found + 1)."""
    n = len(free)
    d = np.where(np.asarray(free) >= free_below, 0, -1)
    nbr = [[] for _ in range(n)]
    for i, j in pairs:
        nbr[i].append(j)
        nbr[j].append(i)
    front = list(np.flatnonzero(d == 0))
    while front:
        nxt = []
        for i in front:
            for j in nbr[i]:
                if d[j] < 0:
                    d[j] = d[i] + 1
                    nxt.append(j)
        front = nxt
    d[d < 0] = d.max() + 1 if d.max() >= 0 else 0
    return d


def _pooled(xs, pairs_at, classify, classes, first_origin):
    nl = len(xs)
    sums = {c: np.zeros(nl) for c in classes}
    counts = {c: np.zeros(nl, dtype=int) for c in classes}
    for o in range(first_origin, nl):
        if len(pairs_at[o]) == 0:
            continue
        p = np.asarray(pairs_at[o])
        cls = classify(o, p)
        rel0 = xs[o, p[:, 0]] - xs[o, p[:, 1]]
        for lag in range(nl - o):
            rel = xs[o + lag, p[:, 0]] - xs[o + lag, p[:, 1]]
            d2 = np.sum((rel - rel0) ** 2, axis=1)
            for c in classes:
                sums[c][lag] += d2[cls[c]].sum()
                counts[c][lag] += int(cls[c].sum())
    return sums, counts


def msrd_by_class(xs, pairs_at, free_at, free_below, first_origin=0):
    """Summed squared relative displacements and pair counts per lag (in samples) and class.
    xs: (samples, cells, 3) centroids; pairs_at[o]: the pairs in contact at sample o; a cell is
    buried at o when free_at[o] < free_below. Every origin–pair counts once (the engine's
    pooling); origins before sample first_origin are left out."""
    def classify(o, p):
        b = np.asarray(free_at[o]) < free_below
        nb = b[p[:, 0]].astype(int) + b[p[:, 1]].astype(int)
        return {"all": np.ones(len(p), bool), "buried-buried": nb == 2,
                "buried-surface": nb == 1, "surface-surface": nb == 0}
    return _pooled(xs, pairs_at, classify, CLASSES, first_origin)


def msrd_by_layer(xs, pairs_at, free_at, free_below, first_origin=0):
    """As msrd_by_class, the pairs split by the depth (`depths`) of the pair's shallower cell at
    the origin: depth 0 touches the surface, depth 2+ is a pair of cells neither of which
    touches a surface cell — the bulk deeper than one layer."""
    def classify(o, p):
        d = depths(pairs_at[o], free_at[o], free_below)
        m = np.minimum(d[p[:, 0]], d[p[:, 1]])
        return {"all": np.ones(len(p), bool), "depth-0": m == 0, "depth-1": m == 1,
                "depth-2+": m >= 2}
    return _pooled(xs, pairs_at, classify, LAYERS, first_origin)


def best_rotation(p, q):
    """The rotation R (3 × 3, det +1) that best carries the points p onto q about their
    centroids (least squares, Kabsch)."""
    pc = p - p.mean(axis=0)
    qc = q - q.mean(axis=0)
    u, _, vt = np.linalg.svd(pc.T @ qc)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    return vt.T @ np.diag([1.0, 1.0, d]) @ u.T


def msrd_less_rotation(xs, pairs_at, first_origin=0):
    """As msrd_by_class's "all", and the same with the aggregate's rigid rotation taken out:
    between each origin o and o + lag every pair's relative vector at o is first turned by the
    rotation that best carries all the cells' centroids at o onto those at o + lag. A rigidly
    turning aggregate moves every pair's relative vector (|Δ|² = 2|d|²(1 − cos φ)) with no cell
    changing its neighbours; what is left is the motion relative to that turn. Returns the
    summed squared displacements (raw, less the rotation), the pair counts and the summed
    rotation angles (degrees, one per origin) per lag, and the origin counts."""
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


def read_geometry(args):
    """Each snapshot's time, cell centroids, contacting pairs and free fractions (cached beside
    the snapshots)."""
    files = sorted(args.snapshots.glob("snap_*.vtp"))
    if not files:
        sys.exit(f"msrd_by_depth: {args.snapshots}: no snapshots (snap_*.vtp)")
    r = args.radius_um
    if r is None:
        spec = args.snapshots.parent / "spec.json"
        r = json.loads(spec.read_text())["cells"]["radius_mean_um"]

    touch = args.touch_um
    # Reading the meshes is the cost (seconds a snapshot): what each gives is kept beside them
    # and reused while that snapshot is unchanged (a run still writing them adds to it).
    cache = args.snapshots / f".msrd_by_depth-touch{touch:g}-r{r:g}.pkl"
    saved = {}
    if cache.exists():
        try:
            saved = pickle.loads(cache.read_bytes())
        except Exception:
            saved = {}
    ts, xs, pairs_at, free_at = [], [], [], []
    fresh = {}
    for k, f in enumerate(files):
        st = f.stat()
        key = (f.name, st.st_size, st.st_mtime_ns)
        if key not in saved:
            t, pts, vcell, tri = read_snapshot(f)
            n = int(vcell.max()) + 1
            x = centroids(pts, vcell, tri, n)
            pairs, free = contacts(pts, vcell, tri, x, n, touch, 3.0 * r)
            saved[key] = (t, x, pairs, free)
        fresh[key] = saved[key]
        t, x, pairs, free = saved[key]
        ts.append(t)
        xs.append(x)
        pairs_at.append(pairs)
        free_at.append(free)
        print(f"\r{k + 1}/{len(files)} snapshots", end="", file=sys.stderr)
    print(file=sys.stderr)
    try:
        cache.write_bytes(pickle.dumps(fresh))
    except OSError:
        pass
    return r, ts, xs, pairs_at, free_at, touch


def save_geometry(path, r, ts, xs, pairs_at, free_at):
    """What the MSRD is computed from, without the meshes: a few tens of kB for a day's run (the
    snapshots are tens of MB, and a saved campaign store keeps none)."""
    counts = np.array([len(p) for p in pairs_at])
    flat = np.array([q for p in pairs_at for q in p], dtype=int).reshape(-1, 2)
    np.savez_compressed(path, r=r, ts=np.asarray(ts), xs=np.asarray(xs), pair_counts=counts,
                        pairs=flat, free=np.asarray(free_at))


def load_geometry(path, radius_um=None):
    g = np.load(path)
    bounds = np.concatenate([[0], np.cumsum(g["pair_counts"])])
    pairs_at = [[tuple(q) for q in g["pairs"][bounds[k]:bounds[k + 1]]]
                for k in range(len(g["ts"]))]
    r = float(g["r"]) if radius_um is None else radius_um
    return r, list(g["ts"]), list(g["xs"]), pairs_at, list(g["free"])


def merge_geometry(parts):
    """Pieces of one run, each (r, ts, xs, pairs_at, free_at), as one in time order: a run that
    spans sessions keeps only its last piece's snapshots in the store (a saved store keeps none),
    so each piece is saved as it ends and the day is put together from them. A snapshot in two
    pieces (the same time) is taken once; pieces of runs with other radii or cell counts are
    refused."""
    r = parts[0][0]
    by_t = {}
    for pr, ts, xs, pairs_at, free_at in parts:
        if pr != r:
            raise ValueError(f"pieces with r = {r} and {pr} µm: not one run")
        for t, x, p, f in zip(ts, xs, pairs_at, free_at):
            if np.shape(x) != np.shape(parts[0][2][0]):
                raise ValueError(f"a snapshot at t = {t:g} s has {len(x)} cells, the first "
                                 f"{len(parts[0][2][0])}: not one run")
            if t in by_t and not np.array_equal(by_t[t][0], x):
                raise ValueError(f"two different snapshots at t = {t:g} s: not one run")
            by_t.setdefault(float(t), (x, p, f))
    ts = sorted(by_t)
    return (r, ts, [by_t[t][0] for t in ts], [by_t[t][1] for t in ts],
            [by_t[t][2] for t in ts])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("snapshots", type=Path, nargs="+",
                    help="the run's snapshot folder or --save-geometry files; several pieces "
                         "of one run (e.g. saved before a campaign stop and after its end) "
                         "are put together in time order")
    ap.add_argument("--radius-um", type=float, default=None,
                    help="r for MSRD / r² (default: the run's spec.json beside the folder)")
    ap.add_argument("--free-below", type=float, default=0.05)
    ap.add_argument("--touch-um", type=float, default=0.5)
    ap.add_argument("--engine-summary", type=Path, default=None)
    ap.add_argument("--csv", type=Path, default=None)
    ap.add_argument("--origins-from", type=float, default=0.0, metavar="SECONDS",
                    help="only time origins at or after this time (e.g. once the doublet has "
                         "fused: the MSRD without the fusion's own flow); the engine's curve "
                         "pools every origin, so --engine-summary compares only at 0")
    ap.add_argument("--save-geometry", type=Path, default=None, metavar="FILE.npz",
                    help="also write what the MSRD is computed from (centroids, contacts, free "
                         "fractions a snapshot) to FILE.npz; give FILE.npz instead of the "
                         "snapshot folder to compute from it")
    ap.add_argument("--less-rotation", action="store_true",
                    help="instead of the classes: all pairs' MSRD as it is and with the "
                         "aggregate's rigid rotation between origin and lag taken out, and the "
                         "mean angle it turned")
    ap.add_argument("--layers", action="store_true",
                    help="split the pairs by depth in the contact graph instead (depth 0: a "
                         "surface cell in the pair; 1: buried, one next to the surface; 2+: "
                         "the bulk deeper than one layer)")
    args = ap.parse_args()

    parts = []
    touch = args.touch_um
    for src in args.snapshots:
        if src.suffix == ".npz":
            parts.append(load_geometry(src, args.radius_um))
        else:
            one = argparse.Namespace(**{**vars(args), "snapshots": src})
            *part, touch = read_geometry(one)
            parts.append(tuple(part))
    try:
        r, ts, xs, pairs_at, free_at = merge_geometry(parts)
    except ValueError as e:
        sys.exit(f"msrd_by_depth: {e}")
    if len(ts) < 3:
        sys.exit("msrd_by_depth: fewer than 3 snapshots")
    if len(parts) > 1:
        gaps = np.diff(ts)
        if np.ptp(gaps) > 1e-6 * max(gaps):
            sys.exit(f"msrd_by_depth: the pieces leave a gap (snapshots {min(gaps):g} to "
                     f"{max(gaps):g} s apart): the lags need evenly spaced snapshots")
    if args.save_geometry:
        save_geometry(args.save_geometry, r, ts, xs, pairs_at, free_at)
    ts = np.array(ts)
    xs = np.array(xs)
    dt = float(np.mean(np.diff(ts)))

    buried0 = free_at[0] < args.free_below
    print(f"r = {r} µm, touch = {touch:.2f} µm, snapshots every {dt:.0f} s, {len(ts)} of them; "
          f"cells buried at t = 0: {int(buried0.sum())} of {len(buried0)}; "
          f"buried over the run (median): "
          f"{int(np.median([(f < args.free_below).sum() for f in free_at]))}")

    lags = np.arange(len(ts)) * dt
    first = int(np.searchsorted(ts, args.origins_from - 1e-9))
    if first >= len(ts) - 2:
        sys.exit(f"msrd_by_depth: --origins-from {args.origins_from}: fewer than 3 snapshots from there")
    if first:
        print(f"origins from t = {ts[first]:.0f} s ({len(ts) - first} of them)")
    if args.less_rotation:
        raw, less, counts, angle, origins = msrd_less_rotation(xs, pairs_at, first)
        nl = len(ts) - first
        has = counts > 0
        y_raw = np.where(has, raw / np.maximum(counts, 1), np.nan) / r**2
        y_less = np.where(has, less / np.maximum(counts, 1), np.nan) / r**2
        turn = np.where(origins > 0, angle / np.maximum(origins, 1), np.nan)
        print()
        print("| lag (s) | origins | MSRD / r² | less the rotation / r² | share of the rotation "
              "| turned (°, mean over origins) |")
        print("|---|---|---|---|---|---|")
        show = sorted(set(np.unique(np.round(np.geomspace(1, nl - 1, 14)).astype(int))))
        for k in show:
            share = 1.0 - y_less[k] / y_raw[k] if y_raw[k] > 0 else float("nan")
            print(f"| {lags[k]:.0f} | {origins[k]} | {y_raw[k]:.3g} | {y_less[k]:.3g} | "
                  f"{share:.0%} | {turn[k]:.1f} |")
        print()
        for name, y in (("as it is", y_raw), ("less the rotation", y_less)):
            mt = mixing(lags, y)
            print(f"mixing time, {name}: " + (f"{mt:.0f} s" if mt is not None
                                              else f"not reached in {lags[nl - 1]:.0f} s"))
        if args.csv:
            with open(args.csv, "w") as f:
                f.write("lag_s,origins,msrd_r2,msrd_less_rotation_r2,turned_deg\n")
                for k in range(nl):
                    f.write(f"{lags[k]:.6g},{origins[k]},{y_raw[k]:.6g},{y_less[k]:.6g},"
                            f"{turn[k]:.6g}\n")
        return
    if args.layers:
        d0 = depths(pairs_at[0], free_at[0], args.free_below)
        print("cells by depth at t = 0: " + ", ".join(
            f"{k}: {int((d0 == k).sum())}" for k in range(int(d0.max()) + 1)))
        sums, counts = msrd_by_layer(xs, pairs_at, free_at, args.free_below, first)
        classes = LAYERS
    else:
        sums, counts = msrd_by_class(xs, pairs_at, free_at, args.free_below, first)
        classes = CLASSES
    curve = {c: np.where(counts[c] > 0, sums[c] / np.maximum(counts[c], 1), np.nan) / r**2
             for c in classes}
    nl = len(ts) - first  # the lags some origin reaches

    eng = None
    if args.engine_summary:
        m = json.loads(args.engine_summary.read_text())["msrd"]
        eng = (np.array(m["lag_s"]), np.array(m["msrd_um2"]) / r**2)

    print()
    hdr = "| lag (s) | " + " | ".join(f"{c} (pairs)" for c in classes)
    print(hdr + ((" | engine, all |" if not first else " | engine, all, every origin |")
                 if eng else " |"))
    print("|" + "---|" * (len(classes) + 1 + (1 if eng else 0)))
    show = sorted(set(np.unique(np.round(np.geomspace(1, nl - 1, 14)).astype(int))))
    for k in show:
        row = f"| {lags[k]:.0f} | " + " | ".join(
            f"{curve[c][k]:.3g} ({counts[c][k]})" for c in classes)
        if eng:
            row += f" | {np.interp(lags[k], eng[0], eng[1]):.3g}"
        print(row + " |")
    print()
    for c in classes:
        mt = mixing(lags, curve[c])
        print(f"mixing time, {c}: " + (f"{mt:.0f} s" if mt is not None
                                       else f"not reached in {lags[nl - 1]:.0f} s"))
    if args.csv:
        with open(args.csv, "w") as f:
            f.write("lag_s," + ",".join(f"msrd_r2_{c},pairs_{c}" for c in classes) + "\n")
            for k in range(nl):
                f.write(f"{lags[k]:.6g}," + ",".join(
                    f"{curve[c][k]:.6g},{counts[c][k]}" for c in classes) + "\n")


if __name__ == "__main__":
    main()
