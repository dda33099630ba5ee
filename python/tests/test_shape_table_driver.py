"""bench/shape_table.py, the study_shape driver's tables (until its CSVs are regenerated):
paired differences, the contact fraction's share of Δq and the window means on synthetic
study_shape output with known answers."""
import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd

_PATH = Path(__file__).resolve().parents[2] / "bench" / "shape_table.py"
_spec = importlib.util.spec_from_file_location("shape_table", _PATH)
st = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(st)


def run(tmp_path, seed, f_by_config, extra_q=None, n_cells=6, times=(0, 60, 120, 180)):
    """One invocation's files: every cell's q = 4.8 + 0.6 f (+ extra_q of its configuration)."""
    extra_q = extra_q or {}
    rows, cells = [], []
    for cfg, f0 in f_by_config.items():
        for t in times:
            fs = f0 + 0.1 * (np.arange(n_cells) - (n_cells - 1) / 2) / n_cells
            qs = 4.8 + 0.6 * fs + extra_q.get(cfg, 0.0)
            for i, (f, q) in enumerate(zip(fs, qs)):
                cells.append({"config": cfg, "t_s": t, "cell": i, "label": i % 2, "q": q,
                              "q_smooth": q - 0.1, "elong": 1.1, "contact_fraction": f})
            rows.append({"config": cfg, "prep_l_eta_reduced": 2, "l_eta_reduced": 0.0,
                         "t_s": t, "theta_deg": 30.0, "q": qs.mean(),
                         "q_smooth": qs.mean() - 0.1, "elong": 1.1,
                         "contact_fraction": fs.mean(), "steps": t, "wall_s": 0.0})
    path = tmp_path / f"prep2-seed{seed}.csv"
    pd.DataFrame(rows).to_csv(path, index=False)
    pd.DataFrame(cells).to_csv(tmp_path / f"prep2-seed{seed}-cells.csv", index=False)
    return path


def test_a_rise_of_the_contact_fraction_accounts_for_all_of_dq_when_q_follows_it(tmp_path):
    p = run(tmp_path, 1, {"0.25": 0.50, "2": 0.45})
    runs, cells = st.load([p])
    assert set(runs.seed) == {1}
    m = st.window_means(runs, 60, 180)
    (seed, prep, name, d, k), = st.paired_differences(m, cells, [("0.25", "2")], 60, 180)
    assert (seed, prep, name) == (1, 2, "0.25 − 2")
    assert abs(d.q - 0.03) < 1e-12 and abs(d.contact_fraction - 0.05) < 1e-12
    assert abs(k - 0.6) < 1e-9
    assert abs(k * d.contact_fraction / d.q - 1) < 1e-9
    assert abs(d.ripple) < 1e-12


def test_a_shift_at_equal_contact_is_not_counted_as_the_contacts(tmp_path):
    # Equal contact fractions, q higher by 0.02 in one configuration: the contact's share is 0.
    p = run(tmp_path, 1, {"0.25": 0.5, "2": 0.5}, extra_q={"0.25": 0.02})
    runs, cells = st.load([p])
    m = st.window_means(runs, 0, 180)
    (_, _, _, d, k), = st.paired_differences(m, cells, [("0.25", "2")], 0, 180)
    assert abs(d.q - 0.02) < 1e-12
    assert abs(k * d.contact_fraction) < 1e-12


def test_seeds_are_summarized_by_their_median_and_range(tmp_path):
    paths = [run(tmp_path, s, {"0.25": 0.45 + df, "2": 0.45})
             for s, df in [(1, 0.01), (2, 0.02), (3, 0.05)]]
    runs, cells = st.load(paths)
    m = st.window_means(runs, 0, 180)
    rows = st.paired_differences(m, cells, [("0.25", "2")], 0, 180)
    assert sorted(r[0] for r in rows) == [1, 2, 3]
    (line,) = st.summarize(rows)
    assert "3 seeds" in line and "Δq +0.0120 (+0.0060 to +0.0300)" in line
    assert "its contact part +0.0120 (+0.0060 to +0.0300)" in line  # all of Δq: q follows f


def test_a_gzipped_cell_file_is_read_as_committed(tmp_path):
    p = run(tmp_path, 1, {"0.25": 0.50, "2": 0.45})
    cells = tmp_path / "prep2-seed1-cells.csv"
    pd.read_csv(cells).to_csv(tmp_path / "prep2-seed1-cells.csv.gz", index=False)
    cells.unlink()
    _, loaded = st.load([p])
    assert loaded is not None and len(loaded) == 2 * 4 * 6


def test_the_report_runs_end_to_end(tmp_path, capsys):
    p = run(tmp_path, 1, {"0.25": 0.5, "2": 0.45, "0.25:x=0": 0.45, "2:x=0": 0.45})
    assert st.main([str(p), "--windows", "0:180", "--pair", "0.25:x=0|2:x=0"]) == 0
    out = capsys.readouterr().out
    assert "0.25 − 2" in out and "0.25:x=0 − 2:x=0" in out
    assert "prepared aggregates" in out and "most in contact" in out
