"""docs/science/tools/probe_table.py: shares, the power balance, MSRD at lags and the torque
probe's columns from foam-run folders, on synthetic samples with known answers."""
import importlib.util
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

_PATH = Path(__file__).resolve().parents[2] / "docs/science/tools/probe_table.py"
_spec = importlib.util.spec_from_file_location("probe_table", _PATH)
pt = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(pt)


def run_folder(path, shares, n=6, spike_at=None, rigid=False, broken_at=None):
    """A foam-run folder whose terms dissipate `shares` of 10 nW (t = 0 without a step)."""
    path.mkdir()
    rows = []
    for k in range(n):
        p = {t: 10 * s for t, s in zip(pt.TERMS, shares)}
        if k == spike_at:
            p["diss_springs_nw"] *= 100
        forces = sum(p.values())
        if k == broken_at:
            forces *= 1.5
        row = {"t_s": float(k), **p, "power_forces_nw": forces, "power_active_nw": 0.25 * forces}
        if k == 0:
            row.update({c: np.nan for c in p} | {"power_forces_nw": np.nan,
                                                 "power_active_nw": np.nan})
        if rigid:
            row.update({"rigid_turn_deg": 0.5 * k, "rigid_drift_um": 0.1 * k})
        rows.append(row)
    pd.DataFrame(rows).to_csv(path / "samples.csv", index=False)
    (path / "spec.json").write_text(json.dumps({"cells": {"xi": 0.25}}))
    return path


def first_row(text):
    """The table's first row as {column: cell}."""
    header, _, row = text.splitlines()[:3]
    return dict(zip(header.strip("| ").split(" | "), row.strip("| ").split(" | ")))


def test_shares_are_medians_the_first_row_has_no_step_and_the_turn_is_the_last(tmp_path):
    f = run_folder(tmp_path / "base", [0.1, 0.6, 0.2, 0.05, 0.05], spike_at=3, rigid=True)
    samples, spec = pt.read_run(f)
    assert len(samples) == 5  # t = 0 dropped
    text, balance = pt.table([("base", samples, spec)])
    row = text.splitlines()[2].strip("| ").split(" | ")
    assert row[:3] == ["base", "0.25", "5"]
    assert row[3:8] == ["10", "60", "20", "5", "5"]  # medium, cortex, ∥, ⊥, springs
    assert row[8] == "25"                            # active / forces
    assert row[9:] == ["2.5", "0.5"]                 # turn and drift at the last sample
    assert balance < 1e-12


def test_a_broken_balance_is_reported_and_runs_without_the_rigid_probe_read(tmp_path):
    a = run_folder(tmp_path / "a", [0.2] * 5, broken_at=2)
    b = run_folder(tmp_path / "b", [0.2] * 5, rigid=True)
    text, balance = pt.table([(f.name, *pt.read_run(f)) for f in (a, b)])
    assert abs(balance - 1 / 3) < 1e-9
    lines = text.splitlines()
    assert lines[2].rstrip().endswith("| — | — |")


def test_a_run_without_the_probe_is_refused_naming_the_key(tmp_path):
    path = tmp_path / "plain"
    path.mkdir()
    pd.DataFrame({"t_s": [0.0], "aspect_ratio": [1.0]}).to_csv(path / "samples.csv", index=False)
    (path / "spec.json").write_text("{}")
    with pytest.raises(ValueError, match="dissipation = true"):
        pt.read_run(path)


def test_friction_share_at_the_cells_scale_reads_the_affine_columns(tmp_path):
    f = run_folder(tmp_path / "affine", [0.2] * 5)
    d = pd.read_csv(f / "samples.csv")
    # medium 3, cortex 1, friction ∥ 4, ⊥ 2 nW at the cells' scale: friction 6 of 10.
    for c, v in zip(pt.AFFINE, [3.0, 1.0, 4.0, 2.0]):
        d[c] = v
    d.to_csv(f / "samples.csv", index=False)
    text, _ = pt.table([("affine", *pt.read_run(f))])
    header, _, row = text.splitlines()[:3]
    col = header.strip("| ").split(" | ").index("friction's share at the cells' scale %")
    assert row.strip("| ").split(" | ")[col] == "60"


def test_the_cells_scale_split_and_the_cortex_ripples_are_medians_of_each_sample(tmp_path):
    f = run_folder(tmp_path / "split", [0.2] * 5)
    d = pd.read_csv(f / "samples.csv")
    # cortex 2 nW (0.2 of 10) at every sample; its ripples 1.5 nW, then one sample at 0.5: the
    # median share is 75 %. At the cells' scale 3 / 1 / 4 / 2 nW, one sample's all doubled.
    d[pt.JITTER] = [np.nan, 1.5, 1.5, 0.5, 1.5, 1.5]
    for c, v in zip(pt.AFFINE, [3.0, 1.0, 4.0, 2.0]):
        d[c] = v
    d.loc[2, pt.AFFINE] *= 2
    d.to_csv(f / "samples.csv", index=False)
    text, _ = pt.table([("split", *pt.read_run(f))])
    cells = first_row(text)
    assert cells["cells' scale: medium / cortex / friction ∥ / ⊥ %"] == "30 / 10 / 40 / 20"
    assert cells["cortex's ripples %"] == "75"


def test_msrd_at_lags_interpolates_the_pooled_curve_and_stops_at_its_end(tmp_path):
    f = run_folder(tmp_path / "m", [0.2] * 5)
    spec = json.loads((f / "spec.json").read_text())
    spec["cells"]["radius_mean_um"] = 2.0
    (f / "spec.json").write_text(json.dumps(spec))
    (f / "summary.json").write_text(json.dumps({
        "msrd": {"lag_s": [60.0, 120.0, 180.0], "msrd_um2": [4.0, 8.0, 20.0]},
        "final_values": {"mixing_time_s": 150.0}}))
    _, spec = pt.read_run(f)
    assert pt.msrd_at(spec["_summary"], 90) == pytest.approx(6.0)
    assert pt.msrd_at(spec["_summary"], 30) == pytest.approx(2.0)   # from 0 at lag 0
    assert np.isnan(pt.msrd_at(spec["_summary"], 240))
    text, _ = pt.table([("m", *pt.read_run(f))], lags=[120, 240])
    cells = first_row(text)
    assert cells["MSRD at the end / r²"] == "5"    # 20 µm² / (2 µm)²
    assert cells["MSRD(120 s) / r²"] == "2"
    assert cells["MSRD(240 s) / r²"] == "—"
    assert cells["mixing (s)"] == "150"


def test_the_torque_probes_columns_are_read_where_the_run_has_them(tmp_path):
    f = run_folder(tmp_path / "t", [0.2] * 5)
    d = pd.read_csv(f / "samples.csv")
    d["rigid_spin_deg_h"] = [np.nan, 1.0, 2.0, 3.0, 4.0, 100.0]   # median of the steps' 3
    d["net_torque_nnum"] = [np.nan, 1e-12, -4e-11, 2e-11, 0.0, 1e-12]
    for c, v in zip(pt.TORQUE_SHARES, [0.84, 0.16, 0.0]):
        d[c] = v
    d.to_csv(f / "samples.csv", index=False)
    text, _ = pt.table([("t", *pt.read_run(f))])
    cells = first_row(text)
    assert cells["spin (°/h)"] == "3"
    assert cells["max |net torque| (nN·µm)"] == "4e-11"
    assert [cells[f"medium's torque: {n} %"] for n in ("cortex", "friction", "springs")] == \
        ["84", "16", "0"]
