"""docs/science/fig9-scaling/activity_scaling.py: the exponents of A_π recovered from synthetic
runs with known ones, the parameters read from each study's way of stating them, and what is left
out."""
import importlib.util
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

_PATH = Path(__file__).resolve().parents[2] / "docs/science/fig9-scaling/activity_scaling.py"
_spec = importlib.util.spec_from_file_location("activity_scaling", _PATH)
asc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(asc)

K, A1, A2, A3 = 1.3, -0.5, 0.25, 0.1
Y0 = {0.3: 1.4, 0.4375: 1.28, 0.75: 1.07}


def truth(p):
    return Y0[p["alpha"]] + 0.2 * asc.a_pi(p, a1=A1, a2=A2, a3=A3) ** K


def write(tmp_path, name, points, seeds=(1, 2, 3), noise=0.0, extra=None, rng=None):
    """A study's runs.csv: one succeeded run per point and seed, Y by `truth` (times a noise)."""
    rows = []
    for settings in points:
        for seed in seeds:
            s = {**settings, "seed": seed, "duration_s": 21600, "numerics.dt_s": 1.0}
            s.update(extra or {})
            try:
                p = asc.parameters(s)
                y = Y0[p["alpha"]] if p["pa_r_over_gamma"] == 0 else truth(p)
            except asc.Skip:
                y = 2.0  # a run the tool leaves out: any value
            if noise:
                y *= 1 + noise * rng.standard_normal()
            rows.append({"run": len(rows), "seed": seed, "settings": json.dumps(s),
                         "job_id": f"j-{name}-{len(rows)}", "state": "succeeded",
                         "unique_contacts_norm": y})
    d = tmp_path / name / "data"
    d.mkdir(parents=True)
    pd.DataFrame(rows).to_csv(d / "runs.csv", index=False)
    return d


def grid(tmp_path, noise=0.0):
    rng = np.random.default_rng(7)
    a = write(tmp_path, "fig8", [{"cells.pa_reduced": pa, "cells.alpha": al}
                                 for pa in (0, 0.165, 0.33, 1) for al in (0.3, 0.4375, 0.75)],
              noise=noise, rng=rng)
    b = write(tmp_path, "fig9", [{"cells.pa_reduced": 0.33, "cells.tau_p_s": t}
                                 for t in (150, 2400)], noise=noise, rng=rng)
    c = write(tmp_path, "fig10", [{"cells.p_a": pa, "cells.gamma": g, "cells.tau_gamma_s": tg}
                                  for pa in (0.0372, 0.1126) for g, tg in ((1.0, 5), (0.25, 20))],
              noise=noise, rng=rng)
    n = write(tmp_path, "fig11", [{"cells.pa_reduced": 0.33, "scene.n_cells": 30}],
              noise=noise, rng=rng)
    return [a, b, c, n]


def test_exact_data_give_back_the_exponents_they_were_made_with(tmp_path):
    df, skipped = asc.load(grid(tmp_path), "unique_contacts_norm", 21600)
    assert not skipped
    act, base, named = asc.with_baseline(df)
    assert not named
    assert base[0.4375] == pytest.approx(1.28)
    est = asc.fit(act)
    assert est["k"] == pytest.approx(K, rel=1e-9)
    assert est["a1"] == pytest.approx(A1, abs=1e-9)
    assert est["a2"] == pytest.approx(A2, abs=1e-9)
    assert est["a3"] == pytest.approx(A3, abs=1e-9)


def test_noisy_data_put_the_true_exponents_inside_the_bootstrap_interval(tmp_path):
    df, _ = asc.load(grid(tmp_path, noise=0.02), "unique_contacts_norm", 21600)
    act, _, _ = asc.with_baseline(df)
    boot = asc.bootstrap(act, 300)
    for name, value in (("k", K), ("a1", A1), ("a2", A2)):
        lo, hi = np.percentile(boot[name], [2.5, 97.5])
        assert lo < value < hi, (name, lo, hi)
    # a walker's a2 (1/2) is far outside it
    assert np.percentile(boot["a2"], 97.5) < 0.5


def test_each_studys_way_of_stating_the_parameters_is_read():
    # fig10 states p_a in kPa and γ, τ_γ = η/γ; the others p_a r/2γ
    p = asc.parameters({"cells.p_a": 0.037162162162162164, "cells.gamma": 1.0,
                        "cells.tau_gamma_s": 5})
    assert p["pa_r_over_gamma"] == pytest.approx(0.33, rel=1e-6)
    assert p["tau_gamma_s"] == 5
    p = asc.parameters({"cells.pa_reduced": 0.33})
    assert p == {"pa_r_over_gamma": 0.66, "alpha": 0.4375, "tau_p_s": 600.0,
                 "tau_gamma_s": 10.0, "n_cells": 20.0}
    # a run with its own cell radius: p_a r/γ with that r
    p = asc.parameters({"cells.p_a": 0.05, "cells.radius_mean_um": 10.0})
    assert p["pa_r_over_gamma"] == pytest.approx(1.0)
    # γ without τ_γ: η stays, τ_γ = η/γ
    assert asc.parameters({"cells.p_a": 0.1, "cells.gamma": 1.0})["tau_gamma_s"] == 5.0


def test_runs_off_the_base_of_what_a_pi_leaves_out_are_named_not_fitted(tmp_path):
    d = write(tmp_path, "fig14", [{"cells.pa_reduced": 0.33, "cells.l_eta_reduced": 0.25}])
    e = write(tmp_path, "odd", [{"cells.pa_reduced": 0.33, "cells.eta_m": 0.1}])
    f = write(tmp_path, "day", [{"cells.pa_reduced": 0.33}], extra={"duration_s": 86400})
    df, skipped = asc.load([d, e, f], "unique_contacts_norm", 21600)
    assert df.empty
    why = {w.split()[0]: r for w, r in skipped}
    assert "L_η/r" in why["fig14"]
    assert why["odd"] == "sets cells.eta_m"
    assert why["day"].startswith("duration 86400")


def test_runs_above_max_pa_are_named_not_fitted(tmp_path):
    d = write(tmp_path, "fig10", [{"cells.p_a": 0.1126, "cells.gamma": g, "cells.tau_gamma_s": tg}
                                  for g, tg in ((1.0, 5), (0.25, 20))])
    df, skipped = asc.load([d], "unique_contacts_norm", 21600, max_pa=1)
    assert len(df) == 3 and np.allclose(df.pa_r_over_gamma / 2, 0.1126 * asc.R_UM / 2)
    assert len(skipped) == 3 and all(r.startswith("p_a r/2γ 2 > --max-pa 1") for _, r in skipped)
    df, skipped = asc.load([d], "unique_contacts_norm", 21600)
    assert len(df) == 6 and not skipped


def test_a_point_without_its_alphas_passive_baseline_is_named(tmp_path):
    d = write(tmp_path, "s", [{"cells.pa_reduced": 0, "cells.alpha": 0.4375},
                              {"cells.pa_reduced": 0.33, "cells.alpha": 0.4375},
                              {"cells.pa_reduced": 0.33, "cells.alpha": 0.75}])
    df, _ = asc.load([d], "unique_contacts_norm", 21600)
    act, _, named = asc.with_baseline(df)
    assert set(act.alpha) == {0.4375}
    assert len(named) == 3 and all("no p_a = 0 runs at α 0.75" in r for _, r in named)


def test_a_shared_run_counts_once(tmp_path):
    a = write(tmp_path, "a", [{"cells.pa_reduced": 0.33}], seeds=(1,))
    b = tmp_path / "b" / "data"
    b.mkdir(parents=True)
    (b / "runs.csv").write_text((a / "runs.csv").read_text())
    df, _ = asc.load([a, b], "unique_contacts_norm", 21600)
    assert len(df) == 1


def test_a_folder_without_runs_exits_2(tmp_path, capsys):
    assert asc.main([str(tmp_path)]) == 2
    assert "no runs.csv" in capsys.readouterr().err


def test_an_unknown_column_exits_2_naming_it(tmp_path, capsys):
    d = write(tmp_path, "s", [{"cells.pa_reduced": 0.33}], seeds=(1,))
    assert asc.main([str(d), "--also", "msrd_end_over_r2"]) == 2
    assert "no column 'msrd_end_over_r2'" in capsys.readouterr().err


def test_the_point_table_shows_the_also_columns(tmp_path, capsys):
    assert asc.main([*map(str, grid(tmp_path)), "--boot", "20", "--also", "seed"]) == 0
    out = capsys.readouterr().out
    assert "| median seed |" in out
    # every point ran seeds 1, 2, 3: the median is 2
    rows = [r for r in out.splitlines() if r.startswith("| 0.") or r.startswith("| 1 |")]
    assert rows and all(r.split("|")[10].strip() == "2" for r in rows)


def test_the_plot_is_written(tmp_path):
    png = tmp_path / "a.png"
    assert asc.main([*map(str, grid(tmp_path)), "--boot", "10", "--plot", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_without_the_baseline_a_falling_metric_gives_its_exponents_with_k_below_0(tmp_path):
    # mixing time = 3e4 · A_π^(−2): no passive part, falls with activity
    rows = []
    for i, s in enumerate([{"cells.pa_reduced": pa, "cells.alpha": al, "cells.tau_p_s": t}
                           for pa in (0.165, 0.33) for al in (0.3, 0.75) for t in (150, 600)]):
        p = asc.parameters(s)
        rows.append({"run": i, "seed": 1, "settings": json.dumps({**s, "duration_s": 21600}),
                     "job_id": f"j-{i}", "state": "succeeded",
                     "mixing_time_s": 3e4 * asc.a_pi(p) ** -2.0})
    d = tmp_path / "m" / "data"
    d.mkdir(parents=True)
    pd.DataFrame(rows).to_csv(d / "runs.csv", index=False)
    df, _ = asc.load([d], "mixing_time_s", 21600)
    act, _, named = asc.with_baseline(df, baseline=False)
    assert not named and len(act) == 8
    est = asc.fit(act)
    assert est["k"] == pytest.approx(-2.0)
    assert est["a1"] == pytest.approx(-0.5) and est["a2"] == pytest.approx(0.25)
