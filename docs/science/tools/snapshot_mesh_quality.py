#!/usr/bin/env python3
"""The meshes cells carry in a run's snapshots (docs/numerics.md, "Remeshing").

    foam export JOB -o DIR            # the job's snapshots as .vtp (ASCII)
    /usr/bin/python3 docs/science/tools/snapshot_mesh_quality.py DIR/snap_*.vtp

Per snapshot: triangles per cell; the mean triangle area against A_ref = 4π r²/N (r from the
cell's own volume, N = numerics.triangles_per_cell, default 320: the area the remesher's
factors refer to); the cell's area against its volume-equivalent sphere's; and the slivers —
the longest edge against ℓ_ref (the equilateral triangle of the cell's mean area), the height
on that edge, the largest angle.
"""
import sys

import numpy as np

import vtp_snapshot

N_NOMINAL = int(next((a.split("=")[1] for a in sys.argv if a.startswith("--triangles=")), 320))


def angle(a, b, c):
    u, v = b - a, c - a
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), (u * v).sum(1)))


for path in (a for a in sys.argv[1:] if not a.startswith("--")):
    t, cid, X, conn = vtp_snapshot.read(path)
    P = X[conn]
    tc = cid[conn[:, 0]]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    vol = np.einsum('ij,ij->i', P[:, 0], np.cross(P[:, 1], P[:, 2])) / 6
    edges = np.stack([np.linalg.norm(P[:, (k + 1) % 3] - P[:, k], axis=1) for k in range(3)], 1)
    largest = np.stack([angle(P[:, k], P[:, (k + 1) % 3], P[:, (k + 2) % 3])
                        for k in range(3)], 1).max(1)
    counts, mean_over_ref, area_over_sphere = [], [], []
    lref = np.zeros(len(conn))
    for c in np.unique(tc):
        m = tc == c
        r = (3 * vol[m].sum() / (4 * np.pi)) ** (1 / 3)
        counts.append(m.sum())
        mean_over_ref.append(area[m].mean() / (4 * np.pi * r * r / N_NOMINAL))
        area_over_sphere.append(area[m].sum() / (4 * np.pi * r * r))
        lref[m] = np.sqrt(4 * area[m].mean() / np.sqrt(3))
    longest = edges.max(1) / lref
    height = 2 * area / edges.max(1) / lref
    print(f"t = {t / 3600:5.1f} h: triangles per cell {min(counts)}–{max(counts)} "
          f"(median {np.median(counts):.0f}); mean area / A_ref {np.median(mean_over_ref):.2f}; "
          f"cell area / sphere's {np.median(area_over_sphere):.3f}; longest edge / ℓ_ref "
          f"p99 {np.percentile(longest, 99):.2f} max {longest.max():.2f}; height / ℓ_ref "
          f"min {height.min():.2f}; largest angle max {largest.max():.0f}° "
          f"(> 150°: {(largest > 150).sum()} of {len(conn)})")
