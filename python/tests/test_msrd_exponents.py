"""docs/science/jam-day/msrd_exponents.py on synthetic MSRD curves with known exponents and
values."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

TOOL = Path(__file__).resolve().parents[2] / "docs/science/jam-day/msrd_exponents.py"
R2 = 8.88 ** 2


def study(tmp_path, curves, radius_um=None):
    """A study's data folder: one succeeded run per (point, seed) with MSRD = c · lag^β µm²
    (radius_um: the runs' settings set cells.radius_mean_um)."""
    d = tmp_path / "s" / "data"
    d.mkdir(parents=True)
    runs, msrd = [], []
    lags = np.arange(60.0, 21601.0, 60.0)
    for i, (x, seed, c, beta) in enumerate(curves):
        job = f"j-{i}"
        settings = {"cells.x": x} if radius_um is None else {"cells.x": x,
                                                              "cells.radius_mean_um": radius_um}
        runs.append({"run": i, "cells.x": x, "seed": seed, "settings": json.dumps(settings),
                     "job_id": job, "state": "succeeded", "mixing_time_s": 1000.0,
                     "t_end_s": 21600.0})
        msrd += [{"job_id": job, "lag_s": lag, "msrd_um2": c * lag ** beta} for lag in lags]
    pd.DataFrame(runs).to_csv(d / "runs.csv", index=False)
    pd.DataFrame(msrd).to_csv(d / "msrd.csv.gz", index=False)
    return d


def run(*args):
    out = subprocess.run([sys.executable, str(TOOL), *map(str, args)], capture_output=True,
                         text=True)
    return out.returncode, out.stdout, out.stderr


def test_exponents_and_the_msrd_at_given_lags_come_back(tmp_path):
    d = study(tmp_path, [(1, 1, 0.01, 1.0), (1, 2, 0.03, 1.0), (2, 1, 0.5, 0.5)])
    rc, out, err = run(d, "--at", "3600")
    assert rc == 0, err
    # the second table: per point, the median of each window's β and of MSRD(3600 s) / r²
    table = out.split("\n\n")[1].splitlines()[2:]
    cells = {row.split("|")[2].strip(): [c.strip() for c in row.split("|")[3:-1]]
             for row in table}
    assert set(cells) == {"cells.x = 1", "cells.x = 2"}
    runs, b1, b2, at = cells["cells.x = 1"]
    assert (runs, float(b1), float(b2)) == ("2", 1.0, 1.0)
    assert abs(float(at) - 0.02 * 3600 / R2) < 1e-3 * 0.02 * 3600 / R2  # median of 0.01, 0.03
    runs, b1, b2, at = cells["cells.x = 2"]
    assert (runs, float(b1), float(b2)) == ("1", 0.5, 0.5)
    assert abs(float(at) - 0.5 * 60 / R2) < 1e-2


def test_a_run_with_its_own_cell_radius_is_read_against_it(tmp_path):
    d = study(tmp_path, [(1, 1, 0.01, 1.0)], radius_um=10.0)
    rc, out, err = run(d, "--at", "3600")
    assert rc == 0, err
    row = out.split("\n\n")[1].splitlines()[2]
    assert abs(float(row.split("|")[-2]) - 0.01 * 3600 / 100.0) < 1e-3 * 0.36


def test_a_bad_lag_list_is_named(tmp_path):
    d = study(tmp_path, [(1, 1, 0.01, 1.0)])
    rc, _, err = run(d, "--at", "ten")
    assert rc != 0 and "--at ten" in err
