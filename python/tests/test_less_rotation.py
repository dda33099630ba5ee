"""docs/science/jam-day/less_rotation.py: the MSRD less the aggregate's rigid turn, on motions
with known answers, and the saved geometries it reads."""
import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("scipy")
_PATH = Path(__file__).resolve().parents[2] / "docs/science/jam-day/less_rotation.py"
_spec = importlib.util.spec_from_file_location("less_rotation", _PATH)
lr = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(lr)


def _rotation(axis, deg):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    t = np.radians(deg)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k


def test_best_rotation_recovers_a_turn_and_ignores_a_shift():
    rng = np.random.default_rng(3)
    p = rng.normal(size=(12, 3))
    rot = _rotation([1, 2, -0.5], 37.0)
    got = lr.best_rotation(p, p @ rot.T + [4.0, -1.0, 2.0])
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
    raw, less, counts, angle, origins = lr.msrd_less_rotation(xs, [pairs] * 6)
    assert counts[3] == len(pairs) * 3 and origins[3] == 3
    assert raw[3] > 1e-3 * counts[3]
    assert np.allclose(less, 0.0, atol=1e-18)
    assert np.allclose(angle[1:] / origins[1:], 2.0 * np.arange(1, 6), atol=1e-9)
    # a pair's |Δ|² under a rigid turn φ is 2|d⊥|²(1 − cos φ), d⊥ its vector across the axis,
    # pooled over origins
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    d2 = sum(np.sum(d ** 2) - np.dot(d, axis) ** 2 for d in (x0[i] - x0[j] for i, j in pairs))
    assert raw[2] == pytest.approx(4 * 2 * d2 * (1 - np.cos(np.radians(4.0))), rel=1e-10)
    # without a turn, the two agree: relative motion is kept whole
    ys = xs[0] + rng.normal(scale=0.2, size=(6, 10, 3)) * np.arange(6)[:, None, None]
    raw2, less2, _, _, _ = lr.msrd_less_rotation(ys, [pairs] * 6)
    assert np.all(less2 <= raw2 + 1e-12)
    assert less2[5] > 0.5 * raw2[5]


def test_origins_before_the_first_are_left_out():
    xs = np.zeros((6, 4, 3))
    xs[:3, 1, 0] = np.arange(3.0)  # cell 1 moves for the first three samples, then rests
    xs[3:, 1, 0] = 2.0
    xs[:, 0, 2] = 5.0
    xs[:, 2, 1] = 4.0
    xs[:, 3] = [-3.0, 1.0, 2.0]
    raw, _, counts, _, origins = lr.msrd_less_rotation(xs, [[(0, 1)]] * 6, first_origin=2)
    assert list(counts) == [4, 3, 2, 1, 0, 0] and list(origins) == [4, 3, 2, 1, 0, 0]
    assert np.all(raw == 0.0)


def test_mixing_interpolates_where_the_curve_crosses_one():
    lags = np.arange(0.0, 3000.0, 100.0)
    assert lr.mixing(lags, lags / 1234.0) == pytest.approx(1234.0)
    assert lr.mixing(lags, lags / 1e6) is None


def _save(path, r, ts, xs, pairs_at):
    counts = np.array([len(p) for p in pairs_at])
    flat = np.array([q for p in pairs_at for q in p], dtype=int).reshape(-1, 2)
    np.savez_compressed(path, r=r, ts=np.asarray(ts), xs=np.asarray(xs), pair_counts=counts,
                        pairs=flat, free=np.zeros((len(ts), len(xs[0]))))


def test_a_saved_geometry_reads_back_and_runs_from_the_command_line(tmp_path):
    ts = [0.0, 3600.0, 7200.0, 10800.0]
    x0 = np.array([[0.0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, 10]])
    xs = [x0 @ _rotation([0, 0, 1], 10.0 * k).T for k in range(4)]
    pairs_at = [[(0, 1), (0, 2)], [], [(0, 3)], [(1, 2)]]
    _save(tmp_path / "g.npz", 8.88, ts, xs, pairs_at)
    r, ts2, xs2, pairs2 = lr.load_geometry(tmp_path / "g.npz")
    assert r == 8.88 and list(ts2) == ts and np.array_equal(xs2, np.array(xs))
    assert [list(map(tuple, p)) for p in pairs2] == pairs_at
    out = subprocess.run([sys.executable, str(_PATH), str(tmp_path / "g.npz"),
                          "--csv", str(tmp_path / "c.csv")],
                         capture_output=True, text=True, check=True).stdout
    assert "mixing time, less the rotation: not reached in 10800 s" in out
    rows = np.genfromtxt(tmp_path / "c.csv", delimiter=",", names=True)
    assert rows["turned_deg"] == pytest.approx([0.0, 10.0, 20.0, 30.0], abs=1e-6)
    assert np.allclose(rows["msrd_less_rotation_r2"], 0.0, atol=1e-20)
    bad = tmp_path / "bad.npz"
    bad.write_text("not a geometry")
    run = subprocess.run([sys.executable, str(_PATH), str(bad)], capture_output=True, text=True)
    assert run.returncode != 0 and "not a saved geometry" in run.stderr
