"""The verdict table (activefoam.study.verdicts) on synthetic study data with known answers."""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from activefoam import study as st
from activefoam.study import verdicts as vd

STUDY = """\
[study]
name = "syn"
seeds = [1, 2, 3]
x = "cells.tau_p_s"
by = "cells.alpha"
[spec]
scene = "fusion"
duration_s = 3600
[[grid]]
"cells.tau_p_s" = [150, 2400]
"cells.alpha" = [0.3, 0.75]
"""


def _data(root: Path, theta, failed=(), settings=None):
    """The study's data folder: θ at the end = theta(τ_p, α, seed); runs in `failed` (τ_p, α,
    seed, kind) failed; settings(τ_p, α, seed): the keys the run was given (runs.csv's JSON)."""
    d = root / "syn" / "data"
    d.mkdir(parents=True)
    rows, samples, msrd = [], [], []
    fails = {(t, a, s): k for t, a, s, k in failed}
    for seed in (1, 2, 3):
        for tau in (150, 2400):
            for a in (0.3, 0.75):
                jid = f"j-{tau}-{a}-{seed}"
                kind = fails.get((tau, a, seed), "")
                rows.append({"run": len(rows), "cells.tau_p_s": tau, "cells.alpha": a,
                             "seed": seed, "job_id": jid,
                             "state": "failed" if kind else "succeeded", "failure_kind": kind,
                             "eq1_ok": 0, "mixing_time_s": 3600})
                if settings is not None:
                    rows[-1]["settings"] = json.dumps(settings(tau, a, seed))
                for t in (0, 1800, 3600):
                    samples.append([jid, t, theta(tau, a, seed), 5.4, 1.0, 3.0, 0.002])
                msrd.append([jid, 3600, 40.0])
    pd.DataFrame(rows).to_csv(d / "runs.csv", index=False)
    pd.DataFrame(samples, columns=["job_id", "t_s"] + st.SAMPLE_COLUMNS).to_csv(
        d / "samples.csv.gz", index=False)
    pd.DataFrame(msrd, columns=["job_id", "lag_s", "msrd_um2"]).to_csv(d / "msrd.csv.gz",
                                                                       index=False)


def _table(tmp: Path, trends_toml: str) -> Path:
    (tmp / "syn.toml").write_text(STUDY)
    f = tmp / "verdicts.toml"
    f.write_text(textwrap.dedent(trends_toml))
    return f


RISE = """\
    [[trend]]
    figure = "F1"
    statement = "θ rises with τ_p"
    study = "syn.toml"
    metric = "theta_end_deg"
    expect = "{expect}"
    low = {{ "cells.tau_p_s" = 150 }}
    high = {{ "cells.tau_p_s" = 2400 }}
    per = "cells.alpha"
    band = 1.0
    """


@pytest.mark.parametrize("expect, verdicts", [
    # At α = 0.3 θ rises by 10° (seed noise ±1°); at α = 0.75 it does not move (±1° noise,
    # the same per seed at both τ_p, so the effect is 0 with an interval of ±2).
    ("increase", ["agrees", "not resolved"]),
    ("decrease", ["disagrees", "not resolved"]),
    ("none", ["disagrees", "not resolved"]),
])
def test_trends_are_judged_per_value_with_their_interval(tmp_path, expect, verdicts):
    f = _table(tmp_path, RISE.format(expect=expect))
    noise = {1: -1.0, 2: 0.0, 3: 1.0}
    _data(tmp_path / "data", lambda tau, a, s: 80 + (10 if (a == 0.3 and tau == 2400) else 0)
          + noise[s] * (1 if tau == 150 else -1))
    t = vd.evaluate(vd.load(f), tmp_path / "data")
    assert list(t["at"]) == ["cells.alpha = 0.3", "cells.alpha = 0.75"]
    assert list(t["verdict"]) == verdicts
    assert t["effect"].iloc[0] == pytest.approx(10.0)
    assert t["effect"].iloc[1] == pytest.approx(0.0)
    assert list(t["n_low"]) == [3, 3] and list(t["n_high"]) == [3, 3]
    # The interval of a 3-against-3 median difference spans the extremes' differences.
    assert t["lo"].iloc[1] == pytest.approx(-2.0) and t["hi"].iloc[1] == pytest.approx(2.0)


def test_a_flat_effect_within_the_band_agrees_with_no_change(tmp_path):
    f = _table(tmp_path, RISE.format(expect="none").replace("band = 1.0", "band = 3.0"))
    noise = {1: -1.0, 2: 0.0, 3: 1.0}
    _data(tmp_path / "data", lambda tau, a, s: 80 + noise[s] * (1 if tau == 150 else -1))
    t = vd.evaluate(vd.load(f), tmp_path / "data")
    assert list(t["verdict"]) == ["agrees", "agrees"]


def test_a_trend_across_points_of_different_steps_says_so(tmp_path):
    """A study may give some points their own step (the p_a r/2γ = 1 points of the figure
    studies): the row of a trend read across them names the keys that differ, low → high."""
    f = _table(tmp_path, RISE.format(expect="increase"))

    def settings(tau, a, seed):
        dt = 0.25 if (a == 0.3 and tau == 2400) else 1.0
        return {"cells.tau_p_s": tau, "cells.alpha": a, "seed": seed, "numerics.dt_s": dt,
                "numerics.cg_tol": 0.01}

    _data(tmp_path / "data", lambda tau, a, s: 80 + (10 if tau == 2400 else 0) + s,
          settings=settings)
    t = vd.evaluate(vd.load(f), tmp_path / "data")
    assert list(t["numerics_differ"]) == ["numerics.dt_s 1.0 → 0.25", ""]
    md = vd.markdown(t)
    assert "**agrees** (the two ensembles ran different numerics: numerics.dt_s 1.0 → 0.25)" in md
    assert md.count("different numerics") == 1


def test_the_table_says_which_numerics_each_study_ran(tmp_path):
    """The verdicts rest on the step each study ran: the table lists its numerics.* settings
    with the runs of each value, ended runs only."""
    f = _table(tmp_path, RISE.format(expect="increase"))

    def settings(tau, a, seed):
        one = not (a == 0.3 and tau == 2400)
        return {"cells.tau_p_s": tau, "cells.alpha": a, "seed": seed,
                "numerics.dt_s": 1.0 if one else 0.25,
                "numerics.contact_within_prisms": one, "numerics.cg_tol": 0.01}

    _data(tmp_path / "data", lambda tau, a, s: 80 + s, settings=settings)
    items = vd.load(f)
    lines = vd.numerics_by_study(items, tmp_path / "data")
    assert lines == ["- syn (12 runs): numerics.cg_tol 0.01 (12); "
                     "numerics.contact_within_prisms false (3), true (9); "
                     "numerics.dt_s 0.25 (3), 1.0 (9)"]
    vd.write(items, tmp_path / "data", tmp_path / "out")
    md = (tmp_path / "out" / "verdicts.md").read_text()
    assert "## The numerics each study ran" in md and lines[0] in md
    # A run still queued is not counted: it has run nothing yet.
    runs_csv = tmp_path / "data" / "syn" / "data" / "runs.csv"
    r = pd.read_csv(runs_csv)
    r.loc[0, "state"] = "queued"
    r.to_csv(runs_csv, index=False)
    assert vd.numerics_by_study(items, tmp_path / "data")[0].startswith("- syn (11 runs)")


def test_too_few_runs_give_no_verdict(tmp_path):
    f = _table(tmp_path, RISE.format(expect="increase"))
    _data(tmp_path / "data", lambda tau, a, s: 80 + (10 if tau == 2400 else 0),
          failed=[(2400, 0.3, 3, "volume-drift")])
    t = vd.evaluate(vd.load(f), tmp_path / "data")
    assert list(t["verdict"]) == ["too few runs", "agrees"]
    assert t["n_high"].iloc[0] == 2
    # The row says why it is short: a failure in the simulation (the supplement's hatched
    # cells), or a run not ended yet; a failure outside the simulation is neither.
    assert "too few runs (failed in the simulation: 1 high) |" in vd.markdown(t)
    runs_csv = tmp_path / "data" / "syn" / "data" / "runs.csv"
    r = pd.read_csv(runs_csv)
    at = (r["cells.tau_p_s"] == 2400) & (r["cells.alpha"] == 0.3)
    r.loc[at & (r["seed"] == 3), "failure_kind"] = "engine-error"
    r.loc[at & (r["seed"] == 2), "state"] = "running"
    r.loc[(r["cells.tau_p_s"] == 150) & (r["cells.alpha"] == 0.3) & (r["seed"] == 1),
          "state"] = "queued"
    r.to_csv(runs_csv, index=False)
    t = vd.evaluate(vd.load(f), tmp_path / "data")
    assert (t["failed_high"].iloc[0], t["pending_high"].iloc[0], t["pending_low"].iloc[0]) == \
        (0, 1, 1)
    assert "too few runs (not ended yet: 1 low, 1 high) |" in vd.markdown(t)


def test_runs_without_a_fit_are_named_where_they_leave_too_few(tmp_path):
    """An arrested fusion has no Eq. 1 fit (θ_eq, τ_f NaN): a row short of runs for that reason
    says how many succeeded runs had no value, not only "too few runs"."""
    f = _table(tmp_path, RISE.format(expect="increase").replace("theta_end_deg",
                                                                "theta_eq_deg"))
    _data(tmp_path / "data", lambda tau, a, s: 80.0)
    runs_csv = tmp_path / "data" / "syn" / "data" / "runs.csv"
    r = pd.read_csv(runs_csv)
    arrested = (r["cells.tau_p_s"] == 2400) & (r["cells.alpha"] == 0.75)
    r["eq1_ok"] = (~arrested).astype(int)
    r["theta_eq_deg"] = 80.0 + r["seed"] + 5.0 * (r["cells.tau_p_s"] == 2400)
    r.to_csv(runs_csv, index=False)
    t = vd.evaluate(vd.load(f), tmp_path / "data")
    assert list(t["verdict"]) == ["agrees", "too few runs"]
    assert list(t["no_value_high"]) == [0, 3] and list(t["no_value_low"]) == [0, 0]
    md = vd.markdown(t)
    assert "too few runs (succeeded runs without a value: 3 high: Eq. 1 did not converge)" in md
    assert md.count("without a value") == 1


def test_fits_longer_than_their_run_are_named_apart_from_unconverged_ones(tmp_path):
    """Eq. 1 converged with τ_f longer than the run extrapolates θ_eq past the data: no value
    (study.derive_metrics), and the row says which of the two reasons left it short."""
    f = _table(tmp_path, RISE.format(expect="increase").replace("theta_end_deg",
                                                                "theta_eq_deg"))
    _data(tmp_path / "data", lambda tau, a, s: 80.0)
    runs_csv = tmp_path / "data" / "syn" / "data" / "runs.csv"
    r = pd.read_csv(runs_csv)
    high = (r["cells.tau_p_s"] == 2400) & (r["cells.alpha"] == 0.75)
    r["eq1_ok"] = (~(high & (r["seed"] == 1))).astype(int)  # seed 1: no convergence
    r["t_end_s"] = 21600.0
    r["tau_f_s"] = np.where(high & (r["seed"] > 1), 44000.0, 2000.0)  # seeds 2, 3: too slow
    r["theta_eq_deg"] = 80.0 + r["seed"] + 5.0 * (r["cells.tau_p_s"] == 2400)
    r.to_csv(runs_csv, index=False)
    t = vd.evaluate(vd.load(f), tmp_path / "data")
    assert list(t["verdict"]) == ["agrees", "too few runs"]
    assert list(t["no_value_high"]) == [0, 3] and list(t["beyond_run_high"]) == [0, 2]
    assert ("3 high: Eq. 1 did not converge (1) or its τ_f is longer than the run (2))"
            in vd.markdown(t))
    r["eq1_ok"] = 1
    r.to_csv(runs_csv, index=False)
    t = vd.evaluate(vd.load(f), tmp_path / "data")
    assert list(t["no_value_high"]) == [0, 2]  # seed 1 now counts: 1 run, still too few
    assert "2 high: Eq. 1's τ_f longer than the run)" in vd.markdown(t)


def test_a_level_and_the_failures_are_judged(tmp_path):
    f = _table(tmp_path, """\
        [[trend]]
        figure = "F2"
        statement = "a granular pile: θ below 90°"
        study = "syn.toml"
        metric = "theta_end_deg"
        expect = "below"
        value = 90
        high = { "cells.tau_p_s" = 150, "cells.alpha" = 0.75 }

        [[trend]]
        figure = "F3"
        statement = "runs fail at long τ_p and low α"
        study = "syn.toml"
        metric = "failed"
        expect = "increase"
        low = { "cells.tau_p_s" = 150, "cells.alpha" = 0.3 }
        high = { "cells.tau_p_s" = 2400, "cells.alpha" = 0.3 }
        """)
    _data(tmp_path / "data", lambda tau, a, s: 85 + s,
          failed=[(2400, 0.3, s, "interpenetration") for s in (1, 2, 3)]
          + [(150, 0.3, 1, "engine-error")])   # not the simulation's: not counted
    t = vd.evaluate(vd.load(f), tmp_path / "data")
    assert list(t["verdict"]) == ["agrees", "too few runs"]
    assert t["effect"].iloc[0] == pytest.approx(87.0)       # the median, below 90 at [86, 88]
    assert t["hi"].iloc[0] == pytest.approx(88.0)
    assert (t["n_low"].iloc[1], t["n_high"].iloc[1]) == (2, 3)
    _data(tmp_path / "data2", lambda tau, a, s: 85 + s,
          failed=[(2400, 0.3, s, "interpenetration") for s in (1, 2, 3)])
    t = vd.evaluate(vd.load(f), tmp_path / "data2")
    assert t["verdict"].iloc[1] == "agrees" and t["effect"].iloc[1] == 1.0
    # Before its study has run, a level row still names its level.
    t = vd.evaluate(vd.load(f), tmp_path / "nothing")
    assert t["verdict"].iloc[0] == "not run yet"
    assert "(below 90)" in vd.markdown(t)


def test_missing_data_is_not_run_yet_and_the_command_writes_the_table(tmp_path):
    f = _table(tmp_path, RISE.format(expect="increase"))
    r = subprocess.run([sys.executable, "-m", "activefoam.study", "verdicts", str(f), "--data",
                        str(tmp_path / "nothing"), "--out", str(tmp_path / "out")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    md = (tmp_path / "out" / "verdicts.md").read_text()
    assert "2 rows: 2 not run yet" in md
    assert f"by `scripts/study.sh verdicts {f} --data {tmp_path / 'nothing'} --out " in md
    assert pd.read_csv(tmp_path / "out" / "verdicts.csv")["verdict"].tolist() == [
        "not run yet", "not run yet"]


def test_the_table_shows_the_figures_of_the_studies_it_judges(tmp_path):
    f = _table(tmp_path, RISE.format(expect="increase"))
    _data(tmp_path / "data", lambda tau, a, s: 80.0 + s)
    vd.write(vd.load(f), tmp_path / "data", tmp_path / "out")
    assert "## The figures" not in (tmp_path / "out" / "verdicts.md").read_text()
    (tmp_path / "data" / "syn" / "syn-trends.png").write_bytes(b"png")
    vd.write(vd.load(f), tmp_path / "data", tmp_path / "out")
    md = (tmp_path / "out" / "verdicts.md").read_text()
    assert "## The figures" in md
    assert "![syn trends](../data/syn/syn-trends.png)" in md and "syn-curves" not in md


@pytest.mark.parametrize("edit, message", [
    (('metric = "theta_end_deg"', 'metric = "theta_end"'),
     "trend[0].metric: 'failed' or one of"),
    (('per = "cells.alpha"', 'per = "cells.alfa"'), "trend[0].per: not a grid key of syn"),
    (('expect = "increase"', 'expect = "up"'), "trend[0].expect: one of increase"),
    (('low = { "cells.tau_p_s" = 150 }', 'low = { "cells.tau_q" = 150 }'),
     "trend[0].low.cells.tau_q: not a grid key of syn"),
    (("band = 1.0", "band = -1.0"), "trend[0].band: a finite number ≥ 0"),
    (('study = "syn.toml"', 'study = "nope.toml"'), "trend[0].study: study: no such file"),
])
def test_bad_verdict_files_exit_2_naming_the_key(tmp_path, edit, message):
    f = _table(tmp_path, RISE.format(expect="increase").replace(*edit))
    r = subprocess.run([sys.executable, "-m", "activefoam.study", "verdicts", str(f), "--data",
                        str(tmp_path), "--out", str(tmp_path / "out")],
                       capture_output=True, text=True)
    assert r.returncode == 2, r.stdout + r.stderr
    assert message in r.stderr, r.stderr


def test_the_projects_verdicts_file_is_valid():
    f = Path(__file__).resolve().parents[2] / "studies" / "verdicts.toml"
    items = vd.load(f)
    assert len(items) >= 30
    # The five reduced figure studies, and the follow-ups that ask why a row disagrees.
    assert {t.study.name for t in items} == {"fig8-reduced", "fig9-reduced", "fig10-reduced",
                                            "fig11-reduced", "fig14-reduced", "fig9-alpha",
                                            "fig9-scaling", "jam-day"}
