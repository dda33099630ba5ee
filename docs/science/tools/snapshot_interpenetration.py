#!/usr/bin/env python3
"""Are cells of a snapshot really inside each other? (docs/science/motion-convergence.md)

    foam export JOB -o DIR            # the job's snapshots as .vtp (ASCII)
    /usr/bin/python3 docs/science/tools/snapshot_interpenetration.py DIR/snap_NNNNNN.vtp [CELL_A CELL_B]

Real interpenetration, over every pair of neighbouring cells: the vertices of one cell inside the
other's closed surface (generalised winding number > 1/2; each cell's own centroid is checked to
have winding 1) and how deep — the distance to the nearest of 28 points sampled on each of the
other cell's triangles (spacing a sixth of an edge, so it overestimates by up to ~0.2 µm on a
320-triangle cell). Junction vertices sit on the neighbour's surface and count as inside at
depth ~0; read the counts beyond 0.3 and 1 µm.

With two cells named: what the contact law and the interpenetration guard read between them —
the facing triangle pairs (centroids within 3 µm, n̂_A·n̂_B < 0) and their centroids' separation
along the pair's bisector n̂ = (n̂_A − n̂_B)/|·|, the direction of the law's gap (negative where
the law sees overlap).
"""
import sys

import numpy as np

import vtp_snapshot

t, cid, X, conn = vtp_snapshot.read(sys.argv[1])
tcell = cid[conn[:, 0]]
cells = np.unique(cid)
cent = np.array([X[cid == c].mean(0) for c in cells])
S = np.array([(i / 6, j / 6, 1 - i / 6 - j / 6) for i in range(7) for j in range(7 - i)])


def tris(c):
    return conn[tcell == c]


def winding(p, T):
    a, b, c = (X[T[:, k]][None] - p[:, None] for k in range(3))
    la, lb, lc = (np.linalg.norm(v, axis=2) for v in (a, b, c))
    det = np.einsum('ijk,ijk->ij', a, np.cross(b, c))
    den = (la * lb * lc + np.einsum('ijk,ijk->ij', a, b) * lc +
           np.einsum('ijk,ijk->ij', b, c) * la + np.einsum('ijk,ijk->ij', c, a) * lb)
    return (2 * np.arctan2(det, den)).sum(1) / (4 * np.pi)


own = np.array([winding(cent[c][None], tris(c))[0] for c in cells])
deep, n03, n1 = [], 0, 0
for P in cells:
    vP = np.nonzero(cid == P)[0]
    for Q in cells:
        if P == Q or np.linalg.norm(cent[P] - cent[Q]) > 25:
            continue
        T = tris(Q)
        ins = vP[winding(X[vP], T) > 0.5]
        if not len(ins):
            continue
        samples = np.einsum('sk,tkd->tsd', S, X[T]).reshape(-1, 3)
        d = np.linalg.norm(X[ins][:, None] - samples[None], axis=2).min(1)
        n03 += int((d > 0.3).sum())
        n1 += int((d > 1).sum())
        deep.append((round(float(d.max()), 2), int(P), int(Q), int((d > 0.3).sum())))
deep.sort(reverse=True)
print(f"t = {t:g} s, {len(cells)} cells, {len(X)} vertices; each cell's own centroid has winding "
      f"{own.min():.3f}–{own.max():.3f}")
print(f"vertices inside another cell deeper than 0.3 µm: {n03}; deeper than 1 µm: {n1}")
print(f"deepest (µm, cell, inside cell, its vertices deeper than 0.3 µm): {deep[:6]}")

if len(sys.argv) > 3:
    A, B = int(sys.argv[2]), int(sys.argv[3])

    def normals(T):
        n = np.cross(X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]])
        return n / np.linalg.norm(n, axis=1)[:, None]

    TA, TB = tris(A), tris(B)
    nA, nB = normals(TA), normals(TB)
    cA, cB = X[TA].mean(1), X[TB].mean(1)
    D = np.linalg.norm(cA[:, None] - cB[None], axis=2)
    i, j = np.nonzero((D < 3.0) & (np.einsum('ik,jk->ij', nA, nB) < 0))
    dots = (nA[i] * nB[j]).sum(1)
    n = nA[i] - nB[j]
    n /= np.linalg.norm(n, axis=1)[:, None]
    g = ((cB[j] - cA[i]) * n).sum(1)
    print(f"cells {A} and {B}: facing pairs with centroids within 3 µm: {len(i)}; bisector "
          f"separation < −0.3 µm: {int((g < -0.3).sum())}, < −1 µm: {int((g < -1).sum())}")
    for k in np.argsort(g)[:8]:
        print(f"  separation {g[k]:+.3f} µm, n̂_A·n̂_B {dots[k]:+.3f}, centroid distance "
              f"{D[i[k], j[k]]:.2f} µm")
