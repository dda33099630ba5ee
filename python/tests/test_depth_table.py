"""docs/science/fig9-depth/depth_table.py: the probe's MSRD by depth at a lag and the mixing
times, from synthetic foam-run folders with known answers."""
import importlib.util
import json
from pathlib import Path

import pandas as pd
import pytest

_PATH = Path(__file__).resolve().parents[2] / "docs/science/fig9-depth/depth_table.py"
_spec = importlib.util.spec_from_file_location("depth_table", _PATH)
dt = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(dt)


def run_folder(path, curves, final, buried=(0, 4, 6, 5, 5), t_s=600.0):
    path.mkdir()
    pd.DataFrame({"t_s": [60.0 * k for k in range(len(buried))],
                  "cells_buried": list(buried)}).to_csv(path / "samples.csv", index=False)
    (path / "spec.json").write_text(json.dumps({"cells": {"radius_mean_um": 2.0},
                                                "scene": {"n_cells": 20}}))
    (path / "summary.json").write_text(json.dumps({"t_s": t_s, "curves": curves,
                                                   "final_values": final}))
    return path


def cells(text):
    header, _, row = text.splitlines()[:3]
    return dict(zip(header.strip("| ").split(" | "), row.strip("| ").split(" | ")))


def test_lags_interpolate_each_class_and_a_class_without_pairs_reads_a_dash(tmp_path):
    curves = {"msrd_surface": {"x": [60, 120, 180], "y": [4.0, 8.0, 20.0]},
              "msrd_mixed": {"x": [60, 120], "y": [2.0, 4.0]},
              "msrd_buried": {"x": [60, 120, 180], "y": [1.0, 2.0, 3.0]},
              "msrd_layer2plus": {"x": [], "y": []}}
    final = {"mixing_time_surface_s": 150.0, "mixing_surface_reached": 1,
             "mixing_time_buried_s": 600.0, "mixing_buried_reached": 0,
             "mixing_time_mixed_s": float("nan"), "mixing_mixed_reached": 0,
             "mixing_time_s": 170.0, "mixing_reached": 1}
    f = run_folder(tmp_path / "r", curves, final)
    c = cells(dt.table([("r", *dt.read_run(f))], 150))
    assert c["cells"] == "2 × 20"
    assert c["buried cells (median)"] == "5"
    assert c["surface–surface at 150 s / r²"] == "3.50"  # 14 µm² / (2 µm)²
    assert c["buried–buried at 150 s / r²"] == "0.62"    # 2.5 µm² / 4
    assert c["surface–buried at 150 s / r²"] == "—"      # past its curve's end
    assert c["depth 2+ at 150 s / r²"] == "—"            # no pairs
    assert c["depth 0 at 150 s / r²"] == "—"             # no curve at all
    assert c["mixing: surface–surface"] == "150 s"
    assert c["mixing: buried–buried"] == "past 600 s"
    assert c["mixing: surface–buried"] == "—"
    assert c["mixing: all pairs"] == "170 s"


def test_a_run_without_the_probe_is_refused_naming_the_key(tmp_path):
    f = run_folder(tmp_path / "plain", {}, {})
    with pytest.raises(ValueError, match="msrd_by_depth = true"):
        dt.read_run(f)
