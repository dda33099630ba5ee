"""bench/hourly_cost.py: a run's cost window by window, from hand-built samples with known costs."""
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[2] / "bench" / "hourly_cost.py"
_spec = importlib.util.spec_from_file_location("hourly_cost", _PATH)
hc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(hc)


def samples(path, pairs=True):
    """Δt 1 s, a sample every 600 s, for 2.5 h: 0.3 s of wall a step in the first hour, 0.45 after
    it; 20 CG iterations a step in the first hour, 30 after; setup 100 s before t = 0."""
    lines = ["t_s,steps,wall_s,cg_iters_mean" + (",contact_pairs" if pairs else "")]
    wall = 100.0
    for k in range(16):
        t = 600.0 * k
        if k:
            wall += 600 * (0.3 if t <= 3600 else 0.45)
        cg = 0 if k == 0 else (20 if t <= 3600 else 30)
        lines.append(f"{t:g},{t:g},{wall:.6f},{cg}" + (f",{1000 + t:g}" if pairs else ""))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_each_window_has_its_own_cost_and_the_last_may_be_shorter(tmp_path):
    rows = hc.read_samples(samples(tmp_path / "s.csv"))
    ws = hc.windows(rows, 3600.0)
    assert [(w[0], w[1], w[2]) for w in ws] == [(0, 3600, 3600), (3600, 7200, 3600),
                                                (7200, 9000, 1800)]
    assert [w[3] / w[2] for w in ws] == pytest.approx([0.3, 0.45, 0.45])
    assert [w[4] for w in ws] == pytest.approx([20, 30, 30])
    # pairs weighted by the steps of each sample's window: the mean of 1600 … 4600
    assert ws[0][5] == pytest.approx(1000 + (600 + 3600) / 2)


def test_from_starts_past_a_resumed_processes_setup(tmp_path):
    rows = hc.read_samples(samples(tmp_path / "s.csv", pairs=False))
    ws = hc.windows(rows, 1200.0, start=4200.0)
    assert ws[0][:3] == (4200, 5400, 1200)
    assert ws[0][3] / ws[0][2] == pytest.approx(0.45) and ws[0][5] is None


def test_the_command_prints_a_row_a_window_and_refuses_what_it_cannot_read(tmp_path):
    out = subprocess.run([sys.executable, str(_PATH), str(samples(tmp_path / "s.csv"))],
                         capture_output=True, text=True, check=True).stdout
    assert "| 1.00–2.00 h | 3600 | 450 | 27.0 | 30.0 | 6700 |" in out
    bad = tmp_path / "bad.csv"
    bad.write_text("t_s,steps\n0,0\n")
    run = subprocess.run([sys.executable, str(_PATH), str(bad)], capture_output=True, text=True)
    assert run.returncode != 0 and "no column 'wall_s'" in run.stderr
    run = subprocess.run([sys.executable, str(_PATH), str(samples(tmp_path / "t.csv")),
                          "--from", "9000"], capture_output=True, text=True)
    assert run.returncode != 0 and "fewer than two samples" in run.stderr
