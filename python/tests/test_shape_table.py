"""docs/science/fig14-friction/shape_table.py: window means, paired differences and the contact
fraction's part of Δq on synthetic shape-probe runs with known answers."""
import importlib.util
from pathlib import Path

import pandas as pd
import pytest

_PATH = (Path(__file__).resolve().parents[2] / "docs" / "science" / "fig14-friction" /
         "shape_table.py")
_spec = importlib.util.spec_from_file_location("shape_table", _PATH)
st = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(st)


def run(out, name, seed, f, extra_q=0.0, slope=0.6, times=(0, 60, 120, 180)):
    """A run whose cells follow q = 4.8 + slope f (+ extra_q at every f): its means do too."""
    d = out / f"{name}-seed{seed}"
    d.mkdir(parents=True)
    rows = [{"t_s": t, "theta_deg": 30.0, "shape_index_mean": 4.8 + slope * f + extra_q,
             "shape_index_smoothed_mean": 4.7 + slope * f + extra_q, "elongation_mean": 1.1,
             "contact_fraction_mean": f, "shape_on_contact_slope": slope,
             "shape_on_contact_intercept": 4.8 + extra_q, "shape_on_contact_r": 0.9}
            for t in times]
    pd.DataFrame(rows).to_csv(d / "samples.csv", index=False)
    (d / "summary.json").write_text("{}")


def test_a_rise_of_the_contact_fraction_accounts_for_all_of_dq_when_q_follows_it(tmp_path):
    run(tmp_path, "L0.25", 1, 0.50)
    run(tmp_path, "L2", 1, 0.45)
    m = st.window_means(st.load(tmp_path), 60, 180)
    (seed, d, part), = st.paired(m, "L0.25", "L2")
    assert seed == 1
    assert d.q == pytest.approx(0.03, abs=1e-12)
    assert d.f == pytest.approx(0.05, abs=1e-12)
    assert part / d.q == pytest.approx(1, abs=1e-9)
    assert abs(d.ripple) < 1e-12


def test_a_shift_at_equal_contact_is_not_counted_as_the_contacts(tmp_path):
    run(tmp_path, "L0.25", 1, 0.5, extra_q=0.02)
    run(tmp_path, "L2", 1, 0.5)
    m = st.window_means(st.load(tmp_path), 0, 180)
    (_, d, part), = st.paired(m, "L0.25", "L2")
    assert d.q == pytest.approx(0.02, abs=1e-12)
    assert abs(part) < 1e-12


def test_only_seeds_both_runs_have_are_paired_and_summarized(tmp_path, capsys):
    for seed, df in [(1, 0.01), (2, 0.03), (3, 0.05)]:
        run(tmp_path, "L0.25", seed, 0.45 + df)
        run(tmp_path, "L2", seed, 0.45)
    run(tmp_path, "L0.25", 4, 0.6)  # no partner: left out
    run(tmp_path, "L2", 5, 0.6)
    run(tmp_path, "L0.25", 5, 0.7)
    (tmp_path / "L2-seed5" / "summary.json").unlink()  # not finished: left out
    m = st.window_means(st.load(tmp_path), 0, 180)
    assert [s for s, _, _ in st.paired(m, "L0.25", "L2")] == [1, 2, 3]
    assert st.paired(m, "L0.25-pa0", "L2") == []
    assert st.main([str(tmp_path), "--windows", "0:180"]) == 0
    out = capsys.readouterr().out
    assert "L0.25 − L2 (3 seeds): Δq +0.0180 (+0.0060 to +0.0300)" in out


def test_runs_without_the_probe_are_refused_by_name(tmp_path):
    d = tmp_path / "L2-seed1"
    d.mkdir()
    pd.DataFrame([{"t_s": 0, "theta_deg": 30.0}]).to_csv(d / "samples.csv", index=False)
    (d / "summary.json").write_text("{}")
    with pytest.raises(ValueError, match="shape = true"):
        st.load(tmp_path)
