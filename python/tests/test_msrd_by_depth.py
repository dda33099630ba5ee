"""docs/science/fig9-depth/msrd_by_depth.py: the geometry it reads contact from, and the MSRD split
by depth, on meshes and motions with known answers."""
import importlib.util
import itertools
from pathlib import Path

import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[2] / "docs/science/fig9-depth/msrd_by_depth.py"
_spec = importlib.util.spec_from_file_location("msrd_by_depth", _PATH)
mbd = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(mbd)


def cube(centre, side=1.0):
    """A closed cube, each face a 3 × 3 grid of vertices (26 vertices, 48 outward triangles)."""
    h = side / 2
    grid = [-h, 0.0, h]
    verts = [np.array(p) for p in itertools.product(grid, grid, grid) if any(abs(c) == h for c in p)]
    index = {tuple(np.round(v, 9)): k for k, v in enumerate(verts)}
    tris = []
    for axis, sign in itertools.product(range(3), (-1, 1)):
        u, w = [a for a in range(3) if a != axis]
        for i, j in itertools.product(range(2), range(2)):
            def at(a, b):
                p = [0.0, 0.0, 0.0]
                p[axis] = sign * h
                p[u] = grid[a]
                p[w] = grid[b]
                return index[tuple(np.round(p, 9))]
            q = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]
            # (u, w, axis) is right-handed for sign +1 when axis follows w cyclically
            outward = sign * (1 if (axis - w) % 3 == 1 else -1)
            if outward < 0:
                q = q[::-1]
            tris += [(q[0], q[1], q[2]), (q[0], q[2], q[3])]
    return np.array(verts) + np.asarray(centre, float), np.array(tris)


def scene(centres, side=1.0):
    pts, vcell, tri = [], [], []
    for c, x in enumerate(centres):
        p, t = cube(x, side)
        tri.append(t + sum(len(q) for q in pts))
        pts.append(p)
        vcell += [c] * len(p)
    return np.concatenate(pts), np.array(vcell), np.concatenate(tri)


def test_point_triangle_distance_in_each_region():
    a, b, c = np.array([[0.0, 0, 0]]), np.array([[1.0, 0, 0]]), np.array([[0.0, 1, 0]])
    p = np.array([[0.2, 0.2, 0.5],   # above the face
                  [2.0, 0.0, 0.0],   # past a vertex
                  [-1.0, -1.0, 0.0],  # past the other vertex, in the plane
                  [0.5, 0.5, 1.0],   # above the hypotenuse's middle
                  [0.5, -2.0, 0.0]])  # beside an edge
    d = mbd.point_triangle_distance(p, a, b, c)[:, 0]
    assert d == pytest.approx([0.5, 1.0, np.sqrt(2.0), 1.0, 2.0])


def test_cube_meshes_are_closed_and_outward():
    pts, vcell, tri = scene([(0.3, -1.2, 2.0)], side=2.0)
    x = mbd.centroids(pts, vcell, tri, 1)
    assert x[0] == pytest.approx([0.3, -1.2, 2.0])
    a, b, c = (pts[tri[:, k]] for k in range(3))
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    assert volume == pytest.approx(8.0)
    edges = {}
    for t in tri:
        for k in range(3):
            e = (t[k], t[(k + 1) % 3])
            edges[e] = edges.get(e, 0) + 1
    assert all(edges.get((j, i)) == 1 for (i, j) in edges)  # each edge once each way


def test_a_grid_of_touching_cubes_buries_only_its_middle():
    centres = list(itertools.product(range(3), range(3), range(3)))
    pts, vcell, tri = scene(centres)
    x = mbd.centroids(pts, vcell, tri, len(centres))
    assert x == pytest.approx(np.array(centres, float))
    pairs, free = mbd.contacts(pts, vcell, tri, x, len(centres), touch_um=0.05, reach_um=1.5)
    middle = centres.index((1, 1, 1))
    assert free[middle] == 0.0
    assert np.all(np.delete(free, middle) > 0.0)
    # every face neighbour touches over a face: a pair
    for i, j in itertools.combinations(range(len(centres)), 2):
        if np.abs(np.subtract(centres[i], centres[j])).sum() == 1:
            assert (i, j) in pairs
    # corner neighbours share one vertex, and cubes apart share none: no pair
    for i, j in pairs:
        assert np.abs(np.subtract(centres[i], centres[j])).max() == 1
        assert np.abs(np.subtract(centres[i], centres[j])).sum() <= 2


def test_separated_cubes_do_not_touch():
    pts, vcell, tri = scene([(0, 0, 0), (1.2, 0, 0)])
    x = mbd.centroids(pts, vcell, tri, 2)
    pairs, free = mbd.contacts(pts, vcell, tri, x, 2, touch_um=0.1, reach_um=5.0)
    assert pairs == []
    assert free == pytest.approx([1.0, 1.0])


def test_msrd_splits_by_the_depth_at_the_origin():
    # cell 0 buried and still, cells 1 and 2 on the surface moving along x and y at unit speed:
    # buried–surface pairs move apart by lag², the surface pair by 2 lag²
    lags = np.arange(6)
    xs = np.zeros((6, 3, 3))
    xs[:, 1, 0] = lags
    xs[:, 2, 1] = lags
    pairs = [[(0, 1), (0, 2), (1, 2)]] * 6
    free = [np.array([0.0, 0.4, 0.4])] * 6
    sums, counts = mbd.msrd_by_class(xs, pairs, free, free_below=0.05)
    n_origins = 6 - lags
    assert list(counts["buried-surface"]) == list(2 * n_origins)
    assert list(counts["surface-surface"]) == list(n_origins)
    assert list(counts["buried-buried"]) == [0] * 6
    assert sums["buried-surface"] / counts["buried-surface"] == pytest.approx(lags**2.0)
    assert sums["surface-surface"] / counts["surface-surface"] == pytest.approx(2.0 * lags**2)
    assert sums["all"] / counts["all"] == pytest.approx(4.0 / 3.0 * lags**2)


def test_a_pair_counts_in_the_class_it_had_at_its_origin():
    # cell 1 is buried at the first origin only: that origin's pair is buried–buried
    xs = np.zeros((3, 2, 3))
    xs[:, 1, 2] = [0.0, 1.0, 2.0]
    free = [np.array([0.0, 0.0]), np.array([0.0, 0.5]), np.array([0.0, 0.5])]
    sums, counts = mbd.msrd_by_class(xs, [[(0, 1)]] * 3, free, free_below=0.05)
    assert list(counts["buried-buried"]) == [1, 1, 1]
    assert list(counts["buried-surface"]) == [2, 1, 0]  # origins 1 and 2
    assert sums["buried-buried"][2] == pytest.approx(4.0)


def test_origins_before_the_first_are_left_out():
    # the pair separates only during the first two samples (a flow), then stays: from origin 2
    # on its MSRD is zero at every lag
    xs = np.zeros((6, 2, 3))
    xs[:, 1, 0] = [0.0, 1.0, 2.0, 2.0, 2.0, 2.0]
    free = [np.array([0.5, 0.5])] * 6
    sums, counts = mbd.msrd_by_class(xs, [[(0, 1)]] * 6, free, 0.05, first_origin=2)
    assert list(counts["all"]) == [4, 3, 2, 1, 0, 0]
    assert np.all(sums["all"] == 0.0)
    sums, counts = mbd.msrd_by_class(xs, [[(0, 1)]] * 6, free, 0.05)
    assert sums["all"][1] / counts["all"][1] == pytest.approx(2.0 / 5.0)


def test_mixing_interpolates_where_the_curve_crosses_one():
    lags = np.arange(0.0, 3000.0, 100.0)
    assert mbd.mixing(lags, lags / 1234.0) == pytest.approx(1234.0)
    assert mbd.mixing(lags, lags / 1e6) is None


def test_depths_count_layers_from_the_surface_through_the_contact_graph():
    # a 5 × 5 × 5 grid of face-touching cells: the outer shell is the surface (98 cells), the
    # next shell buried next to it (26), the middle one two layers down
    centres = list(itertools.product(range(5), range(5), range(5)))
    index = {c: k for k, c in enumerate(centres)}
    pairs = [(index[a], index[b]) for a, b in itertools.combinations(centres, 2)
             if np.abs(np.subtract(a, b)).sum() == 1]
    shell = np.array([min(min(c), 4 - max(c)) for c in centres])
    free = np.where(shell == 0, 0.3, 0.0)
    d = mbd.depths(pairs, free, 0.05)
    assert list(d) == list(shell)
    assert [(d == k).sum() for k in range(3)] == [98, 26, 1]
    # a buried cluster cut off from the surface lies deeper than everything reached
    d = mbd.depths([(0, 1), (2, 3)], np.array([0.5, 0.0, 0.0, 0.0]), 0.05)
    assert list(d) == [0, 1, 2, 2]


def test_msrd_by_layer_splits_by_the_shallower_cells_depth():
    # a chain surface(0) – buried(1) – buried(2) – buried(3): pairs (0,1) at depth 0, (1,2) at
    # depth 1, (2,3) at depth 2; only cell 3 moves, at unit speed along z
    xs = np.zeros((4, 4, 3))
    xs[:, 3, 2] = np.arange(4)
    free = [np.array([0.5, 0.0, 0.0, 0.0])] * 4
    pairs = [[(0, 1), (1, 2), (2, 3)]] * 4
    sums, counts = mbd.msrd_by_layer(xs, pairs, free, 0.05)
    assert list(counts["depth-0"]) == list(counts["depth-1"]) == list(counts["depth-2+"]) \
        == [4, 3, 2, 1]
    assert np.all(sums["depth-0"] == 0.0) and np.all(sums["depth-1"] == 0.0)
    assert sums["depth-2+"] / counts["depth-2+"] == pytest.approx(np.arange(4.0) ** 2)
    assert list(counts["all"]) == [12, 9, 6, 3]


def _rotation(axis, deg):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    t = np.radians(deg)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k


def test_best_rotation_recovers_a_turn_and_ignores_a_shift():
    rng = np.random.default_rng(3)
    p = rng.normal(size=(12, 3))
    rot = _rotation([1, 2, -0.5], 37.0)
    got = mbd.best_rotation(p, p @ rot.T + [4.0, -1.0, 2.0])
    assert np.allclose(got, rot, atol=1e-12)
    assert np.isclose(np.linalg.det(got), 1.0)


def test_a_rigidly_turning_aggregate_has_msrd_but_none_less_the_rotation():
    rng = np.random.default_rng(4)
    x0 = rng.normal(scale=3.0, size=(10, 3))
    pairs = [(i, j) for i in range(10) for j in range(i + 1, 10)
             if np.linalg.norm(x0[i] - x0[j]) < 6]
    assert len(pairs) > 5
    # 2° a sample about a fixed axis, and a drift of the whole
    xs = np.array([x0 @ _rotation([0.3, -0.5, 0.8], 2.0 * k).T + 0.7 * k for k in range(6)])
    raw, less, counts, angle, origins = mbd.msrd_less_rotation(xs, [pairs] * 6)
    assert counts[3] == len(pairs) * 3 and origins[3] == 3
    assert raw[3] > 1e-3 * counts[3]
    assert np.allclose(less, 0.0, atol=1e-18)
    assert np.allclose(angle[1:] / origins[1:], 2.0 * np.arange(1, 6), atol=1e-9)
    # without a turn, the two agree: relative motion is kept whole
    ys = xs[0] + rng.normal(scale=0.2, size=(6, 10, 3)) * np.arange(6)[:, None, None]
    raw2, less2, _, _, _ = mbd.msrd_less_rotation(ys, [pairs] * 6)
    assert np.all(less2 <= raw2 + 1e-12)
    assert less2[5] > 0.5 * raw2[5]


def test_saved_geometry_reads_back_as_it_was(tmp_path):
    ts = [0.0, 3600.0, 7200.0]
    xs = [np.arange(12.0).reshape(4, 3) + k for k in range(3)]
    pairs_at = [[(0, 1), (1, 2)], [], [(0, 3)]]
    free_at = [np.array([0.5, 0.0, 0.2, 1.0])] * 3
    mbd.save_geometry(tmp_path / "g.npz", 8.88, ts, xs, pairs_at, free_at)
    r, ts2, xs2, pairs2, free2 = mbd.load_geometry(tmp_path / "g.npz")
    assert r == 8.88 and ts2 == ts
    assert [list(map(tuple, p)) for p in pairs2] == pairs_at
    assert np.array_equal(np.array(xs2), np.array(xs)) and np.array_equal(free2, free_at)


def test_pieces_of_a_run_put_together_are_the_run(tmp_path):
    rng = np.random.default_rng(7)
    ts = [3600.0 * k for k in range(7)]
    xs = [rng.normal(size=(5, 3)) for _ in ts]
    pairs_at = [[(0, k % 5), (1, 2)] for k in range(7)]
    free_at = [rng.uniform(size=5) for _ in ts]
    whole = (8.88, ts, xs, pairs_at, free_at)
    # saved before a stop (0–3 h) and after the end (3–6 h: the 3 h snapshot in both), given
    # in either order
    first = (8.88, ts[:4], xs[:4], pairs_at[:4], free_at[:4])
    last = (8.88, ts[3:], xs[3:], pairs_at[3:], free_at[3:])
    mbd.save_geometry(tmp_path / "a.npz", *first)
    mbd.save_geometry(tmp_path / "b.npz", *last)
    for order in (["a", "b"], ["b", "a"]):
        r, ts2, xs2, pairs2, free2 = mbd.merge_geometry(
            [mbd.load_geometry(tmp_path / f"{n}.npz") for n in order])
        assert r == 8.88 and ts2 == ts
        assert np.array_equal(np.array(xs2), np.array(xs))
        assert [list(map(tuple, p)) for p in pairs2] == pairs_at
        assert np.array_equal(np.array(free2), np.array(free_at))
    other = list(xs[3:])
    other[0] = other[0] + 1.0
    with pytest.raises(ValueError, match="two different snapshots at t = 10800"):
        mbd.merge_geometry([first, (8.88, ts[3:], other, pairs_at[3:], free_at[3:])])
    with pytest.raises(ValueError, match="r = 8.88 and 9"):
        mbd.merge_geometry([first, (9.0, ts[3:], xs[3:], pairs_at[3:], free_at[3:])])
    with pytest.raises(ValueError, match="has 4 cells"):
        mbd.merge_geometry([first, (8.88, [25200.0], [xs[0][:4]], [[]], [free_at[0][:4]])])
