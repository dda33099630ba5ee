"""docs/science/fig14-friction/dissipation_table.py: shares, MSRD crossings and the power balance
on synthetic samples with known answers."""
import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd

_PATH = Path(__file__).resolve().parents[2] / "docs/science/fig14-friction/dissipation_table.py"
_spec = importlib.util.spec_from_file_location("dissipation_table", _PATH)
dt = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(dt)


def samples(config, shares, msrd_per_s, n=11, every=60.0, spike_at=None):
    """Samples whose terms dissipate `shares` of a power of 10 (a spike of the springs at one)."""
    rows = []
    for k in range(n):
        p = {t: 10 * s for t, s in zip(dt.TERMS, shares)}
        if k == spike_at:
            p["p_spring_implicit"] *= 100
        row = {"config": config, "l_eta_reduced": 0.5, "xi": 0.25, "t_s": k * every, **p,
               "p_forces": sum(p.values()), "p_active": 1.0,
               "p_cortex_vertex_scale": 0.9 * p["p_cortex"], "v_relative_um_min": 0.5,
               "msrd_um2": msrd_per_s * k * every, "unique_contacts": 1.0}
        row.update({t: 1.0 for t in dt.AFFINE})
        rows.append(row)
    return pd.DataFrame(rows)


def test_shares_are_medians_that_one_spike_does_not_move():
    d = samples("a", [0.1, 0.6, 0.2, 0.05, 0.05], 0.0, spike_at=3)
    text, balance = dt.table([d], 1.0, [60])
    row = text.splitlines()[2].split(" | ")
    assert row[2:7] == ["10", "60", "20", "5", "5"]        # medium, cortex, ∥, ⊥, springs
    assert row[7] == "90"                                   # cortex at vertex scale
    assert row[8:12] == ["25", "25", "25", "25"]            # cell scale: equal affine parts
    assert balance < 1e-12


def test_msrd_reaches_r2_where_the_line_crosses_it():
    # MSRD = 0.01 r²/s with r = 2 µm: r² = 4 µm² at 100 s, between samples at 60 and 120 s.
    d = samples("a", [0.2] * 5, 0.04)
    text, _ = dt.table([d], 2.0, [120, 6000])
    row = text.splitlines()[2].strip("| ").split(" | ")
    assert row[-3] == "1.20" and row[-2] == "—" and row[-1] == "100"
    assert np.isnan(dt.crossing(np.array([0.0, 1.0]), np.array([0.0, 0.5]), 1.0))


def test_a_broken_balance_is_reported():
    d = samples("a", [0.2] * 5, 0.0)
    d.loc[2, "p_forces"] *= 1.5
    _, balance = dt.table([d], 1.0, [60])
    assert abs(balance - 1 / 3) < 1e-9


def test_configurations_keep_their_order_and_rows():
    d = pd.concat([samples("0.5", [0.2] * 5, 0.0), samples("0.125", [0.2] * 5, 0.0)])
    text, _ = dt.table([d], 1.0, [60])
    assert [r.split(" | ")[0].strip("| ") for r in text.splitlines()[2:]] == ["0.5", "0.125"]
