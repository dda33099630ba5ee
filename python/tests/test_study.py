"""Studies as files (activefoam.study) through a real foamd: run, interrupt, rerun, report; and
bad study files."""

import io
import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from activefoam import study as st
from activefoam.study import matching, submission
from conftest import TINY_FUSION


def _run(args, foamd=None, timeout=300, **kw):
    env = dict(os.environ)
    if foamd is not None:
        env["FOAM_SERVER"] = foamd.address
    return subprocess.run([sys.executable, "-m", "activefoam.study", *args], env=env,
                          capture_output=True, text=True, timeout=timeout, **kw)


BASE = TINY_FUSION


def _study(tmp: Path, seeds, name="tiny", extra="") -> Path:
    (tmp / "base.toml").write_text(BASE)
    f = tmp / f"{name}-{len(seeds)}.toml"
    f.write_text(textwrap.dedent(f"""\
        [study]
        name = "{name}"
        title = "tiny fusion"
        base = "base.toml"
        seeds = {seeds}
        x = "cells.alpha"
        [spec]
        duration_s = 240
        [[grid]]
        "cells.alpha" = [0.4375, 0.6]
        [fitness]
        key = "cells.alpha"
        reference = 0.4375
        """) + extra)
    return f


def test_run_interrupt_rerun_report(foamd, client, tmp_path):
    one_seed = _study(tmp_path, [1])
    two_seeds = _study(tmp_path, [1, 2])
    # A first study run holds seed 1 only, and returns at once.
    r = _run(["run", str(one_seed), "--no-wait"], foamd)
    assert r.returncode == 0, r.stderr
    assert "2 runs submitted, 0 already" in r.stderr
    # The full study, interrupted while it waits: seed 1's runs are not submitted again.
    env = dict(os.environ, FOAM_SERVER=foamd.address)
    p = subprocess.Popen([sys.executable, "-m", "activefoam.study", "run", str(two_seeds)],
                         env=env, stderr=subprocess.PIPE, text=True)
    line = p.stderr.readline()
    assert "2 runs submitted, 2 already" in line, line
    time.sleep(1)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert "nothing is submitted twice" in err
    # One job is lost meanwhile (cancelled): the rerun submits it again, and nothing else.
    jobs = client.jobs(tag="study:tiny")
    assert len(jobs) == 4
    victim = jobs[jobs["state"].isin(["queued", "running"])]["job_id"].iloc[0]
    client.cancel(victim, "test: a lost run")
    while client.job(victim).state() not in ("cancelled", "succeeded", "failed"):
        time.sleep(0.2)
    r = _run(["run", str(two_seeds)], foamd, timeout=600)
    lost = client.job(victim).state() == "cancelled"
    assert f"{1 if lost else 0} runs submitted, {3 if lost else 4} already" in r.stderr, r.stderr
    assert r.returncode == 0, r.stderr
    jobs = client.jobs(tag="study:tiny")
    assert len(jobs) == (5 if lost else 4)
    assert (jobs["state"] == "succeeded").sum() == 4
    # Once more: everything is held, nothing is submitted.
    r = _run(["run", str(two_seeds), "--no-wait"], foamd)
    assert "0 runs submitted, 4 already" in r.stderr, r.stderr
    assert len(client.jobs(tag="study:tiny")) == len(jobs)

    # The report, from the store alone.
    out = tmp_path / "report"
    r = _run(["report", str(two_seeds), "--out", str(out)], foamd)
    assert r.returncode == 0, r.stderr
    for f in ("summary.csv", "summary.md", "tiny-curves.png", "tiny-trends.png", "fitness.csv",
              "fitness.md", "tiny-theta-bands.png", "data/runs.csv", "data/samples.csv.gz",
              "data/msrd.csv.gz"):
        assert (out / f).is_file() and (out / f).stat().st_size > 0, f
    runs = pd.read_csv(out / "data/runs.csv")
    assert len(runs) == 4 and (runs["state"] == "succeeded").all()
    assert sorted(runs["seed"]) == [1, 1, 2, 2]
    samples = pd.read_csv(out / "data/samples.csv.gz")
    assert set(samples["job_id"]) == set(runs["job_id"])
    assert len(samples[samples["job_id"] == runs["job_id"][0]]) == 240 // 30 + 1
    # The MSRD curves came through the store (GetResults curves), one per run.
    msrd = pd.read_csv(out / "data/msrd.csv.gz")
    assert set(msrd["job_id"]) == set(runs["job_id"])
    curve = client.job(runs["job_id"][0]).curve("msrd")
    assert len(curve) == len(msrd[msrd["job_id"] == runs["job_id"][0]])
    summary = pd.read_csv(out / "summary.csv")
    assert list(summary["runs"]) == [2, 2] and list(summary["succeeded"]) == [2, 2]
    # θ at the end is the last sample's θ, per run, and its median per point.
    last = samples.sort_values("t_s").groupby("job_id")["theta_deg"].last()
    data = st.load_data(st.load(two_seeds), out / "data")
    for jid, theta in last.items():
        got = data.runs.loc[data.runs["job_id"] == jid, "theta_end_deg"].iloc[0]
        assert got == pytest.approx(theta)
    # Two seeds a point: the fitness table judges nothing (no verdict under 3 runs).
    fit = pd.read_csv(out / "fitness.csv")
    assert (fit["fit"] == "—").all()
    assert "not decided" in (out / "fitness.md").read_text()
    # The same tables again from the data folder alone (no foamd).
    again = tmp_path / "again"
    r = _run(["report", str(two_seeds), "--from-data", str(out / "data"), "--out", str(again)],
             None)
    assert r.returncode == 0, r.stderr
    assert (again / "summary.csv").read_text() == (out / "summary.csv").read_text()


BAD = [
    ("[study]\nname = 'x'\nseed = [1]\n", "study.seed: unknown key (did you mean 'seeds'?)"),
    ("[study]\nname = 'x'\nseeds = []\n", "study.seeds"),
    ("[study]\nname = 'a b'\nseeds = [1]\n", "study.name"),
    ("[study]\nname = 'x'\nseeds = [1]\npreset = 'fast'\n", "study.preset"),
    ("[study]\nname = 'x'\nseeds = [1]\n[spec]\nscene = 'fusion'\n", "grid: at least one"),
    ("[study]\nname = 'x'\nseeds = [1]\n[spec]\nscene = 'fusion'\n[[grid]]\n'cells.alpha' = []\n",
     "grid[0].cells.alpha"),
    ("[study]\nname = 'x'\nseeds = [1]\nx = 'cells.gamma'\n[spec]\nscene = 'fusion'\n"
     "[[grid]]\n'cells.alpha' = [0.5]\n", "study.x"),
    ("[study]\nname = 'x'\nseeds = [1]\n[spec]\nscene = 'fusion'\n[[grid]]\n"
     "'cells.alpha' = [0.5]\n[fitness]\nkey = 'cells.alpha'\nreference = 0.7\n",
     "fitness.reference"),
    ("[study]\nname = 'x'\nseeds = [1]\n[[grid]]\n'cells.alpha' = [0.5]\n", "spec.scene"),
    ("[study\nname = 'x'\n", "not TOML"),
    ("[studdy]\n", "studdy: unknown key (did you mean 'study'?)"),
    ("[study]\nname = 'x'\nseeds = [1]\n[spec]\nscene = 'fusion'\n[[grid]]\n"
     "'cells.alpha' = [0.5]\n[[diagnose]]\nname = 'k'\n", "diagnose[0].spec"),
    ("[study]\nname = 'x'\nseeds = [1]\n[spec]\nscene = 'fusion'\n[[grid]]\n"
     "'cells.alpha' = [0.5]\n[[diagnose]]\nname = 'k'\nspec = { 'cells.alpha' = 0.6 }\n",
     "diagnose[0].spec.cells.alpha: a diagnosis reruns the same point and seed with other "
     "numerics"),
    ("[study]\nname = 'x'\nseeds = [1]\n[spec]\nscene = 'fusion'\n[[grid]]\n"
     "'cells.alpha' = [0.5]\n[[diagnose]]\nname = 'k'\nspec = { 'numerics.dt_s' = 0.25 }\n"
     "kinds = ['volume-drfit']\n", "diagnose[0].kinds"),
    ("[study]\nname = 'x'\nseeds = [1]\n[spec]\nscene = 'fusion'\n[[grid]]\n"
     "'cells.alpha' = [0.5]\n[[diagnose]]\nname = 'k'\nspec = { 'numerics.dt_s' = 0.25 }\n"
     "kind = ['volume-drift']\n", "diagnose[0].kind: unknown key (did you mean 'kinds'?)"),
    ("[study]\nname = 'x'\nseeds = [1]\n[spec]\nscene = 'fusion'\n'numerics.dt_s' = 0.25\n"
     "[[grid]]\n'cells.alpha' = [0.5]\n[[diagnose]]\nname = 'k'\n"
     "spec = { 'numerics.dt_s' = 0.25 }\n",
     "diagnose[0].spec: the study's [spec] already sets numerics.dt_s = 0.25"),
    ("[study]\nname = 'x'\nseeds = [1]\ndiagnose = 'no'\n[spec]\nscene = 'fusion'\n[[grid]]\n"
     "'cells.alpha' = [0.5]\n", "study.diagnose: true"),
    ("[study]\nname = 'x'\nseeds = [1]\ndiagnose = false\n[spec]\nscene = 'fusion'\n"
     "[[grid]]\n'cells.alpha' = [0.5]\n[[diagnose]]\nname = 'k'\n"
     "spec = { 'numerics.dt_s' = 0.25 }\n",
     "study.diagnose: false turns the diagnoses off, but the file has [[diagnose]] tables"),
]


@pytest.mark.parametrize("text,message", BAD)
def test_bad_study_files_exit_2_naming_the_key(tmp_path, text, message):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    r = _run(["check", str(f)])
    assert r.returncode == 2, r.stdout + r.stderr
    assert message in r.stderr


def test_a_changed_study_names_its_stale_jobs_and_cancels_them_when_asked(foamd, client,
                                                                          tmp_path):
    import re
    f = _study(tmp_path, [1], name="stale")
    r = _run(["run", str(f), "--no-wait"], foamd)
    assert r.returncode == 0 and "2 runs submitted" in r.stderr, r.stderr
    old = set(client.jobs(tag="study:stale")["job_id"])
    # The step changed (as a study moving to another Δt): the two jobs are no runs of it now.
    f.write_text(f.read_text().replace("duration_s = 240", "duration_s = 240\n"
                                       '"numerics.cg_tol" = 0.001'))
    r = _run(["run", str(f), "--no-wait"], foamd)
    assert r.returncode == 0 and "2 runs submitted" in r.stderr, r.stderr
    named = re.search(r"(\d+) queued or running jobs of tag study:stale are no run .*\((.*)\)",
                      r.stderr)
    if named:  # (both may have finished meanwhile: then nothing is named, nothing to cancel)
        assert set(named.group(2).split(", ")) <= old and "--cancel-stale" in r.stderr
    r = _run(["run", str(f), "--no-wait", "--cancel-stale"], foamd)
    assert r.returncode == 0 and "0 runs submitted, 2 already" in r.stderr, r.stderr
    deadline = time.monotonic() + 30   # a job told to stop ends at its next step
    while True:
        jobs = client.jobs(tag="study:stale").set_index("job_id")["state"]
        if all(jobs[j] != "running" for j in old) or time.monotonic() > deadline:
            break
        time.sleep(0.2)
    for j in old:   # every old job is cancelled or had ended on its own
        assert jobs[j] in ("cancelled", "succeeded", "failed"), (j, jobs[j])
    told = re.search(r"cancelled (\d+) jobs that are no run .*\((.*)\)(?:; (\d+) of them run)?",
                     r.stderr)
    in_store = sum(jobs[j] == "cancelled" for j in old)
    if told:   # the count is the server's answer: a running job may still end on its own
        assert set(told.group(2).split(", ")) <= old
        told_n, stopping = int(told.group(1)), int(told.group(3) or 0)
        assert told_n - stopping <= in_store <= told_n, (r.stderr, dict(jobs))
    else:
        assert in_store == 0, r.stderr
    # The file's own runs are not touched.
    assert set(jobs.drop(index=list(old))) <= {"queued", "running", "succeeded"}
    deadline = time.time() + 60
    while any(client.job(j).state() == "running" for j in old):
        assert time.time() < deadline, "a cancelled job still runs after 60 s"
        time.sleep(0.2)  # a cancelled running job stops at its next step


def test_a_spec_foamd_refuses_submits_nothing(foamd, client, tmp_path):
    f = _study(tmp_path, [1], name="refused")
    text = f.read_text().replace('"cells.alpha" = [0.4375, 0.6]', '"cells.alpha" = [0.5, 1.5]')
    text = text.replace("reference = 0.4375", "reference = 0.5")
    f.write_text(text)
    r = _run(["run", str(f), "--no-wait"], foamd)
    assert r.returncode == 2, r.stderr
    assert "cells.alpha" in r.stderr
    # The valid point went in first and was cancelled: the study is submitted whole or not at all.
    jobs = client.jobs(tag="study:refused")
    assert (jobs["state"] == "cancelled").all()


@pytest.mark.parametrize("path", sorted(
    p for p in (Path(__file__).resolve().parents[2] / "studies").glob("*.toml")
    if p.name != "verdicts.toml"), ids=lambda p: p.name)
def test_every_committed_study_file_reads(path):
    # A study file is read before anything is submitted; a typo in a cluster's full-scale file
    # should fail here, not on the cluster.
    study = st.load(path)
    assert study.points() and study.seeds
    if study.fitness is None and "fitness" not in study.name:
        assert len(study.seeds) >= 2  # figure studies: no trend from fewer (fig9-size: 2)


def test_missing_data_folder_is_a_clear_error(tmp_path):
    f = _study(tmp_path, [1])
    r = _run(["report", str(f), "--from-data", str(tmp_path / "nowhere")])
    assert r.returncode == 2 and "runs.csv is missing" in r.stderr


def test_points_are_the_union_of_the_grids(tmp_path):
    f = _study(tmp_path, [1, 2], extra='[[grid]]\n"cells.alpha" = [0.6, 0.75]\n')
    s = st.load(f)
    assert [p["cells.alpha"] for p in s.points()] == [0.4375, 0.6, 0.75]
    assert len(s.runs()) == 6
    # A run's identity does not depend on the other runs.
    run = s.runs()[0]
    assert st.load(_study(tmp_path, [1])).run_id(run) == s.run_id(run)


def _write_data(d: Path, rows, samples, msrd):
    """A report's data folder (what `collect` writes) from plain rows."""
    pd.DataFrame(rows).to_csv(d / "runs.csv", index=False)
    pd.DataFrame(samples, columns=["job_id", "t_s"] + st.SAMPLE_COLUMNS).to_csv(
        d / "samples.csv.gz", index=False)
    pd.DataFrame(msrd, columns=["job_id", "lag_s", "msrd_um2"]).to_csv(d / "msrd.csv.gz",
                                                                       index=False)


def _synthetic(tmp: Path, shift_theta: float, failed_seed: int = 0):
    """A preset-fitness study's data folder with known answers: θ(t) = 40 + 5 t/h + seed noise
    (draft shifted by shift_theta), and one failed draft run."""
    f = tmp / "fit.toml"
    f.write_text(textwrap.dedent("""\
        [study]
        name = "synthetic"
        seeds = [1, 2, 3, 4, 5]
        x = "numerics.preset"
        [spec]
        scene = "fusion"
        duration_s = 7200
        [[grid]]
        "numerics.preset" = ["draft", "standard"]
        [fitness]
        key = "numerics.preset"
        reference = "standard"
        metrics = ["theta_end_deg", "shape_index_end", "msrd_end_over_r2"]
        """))
    d = tmp / "data"
    d.mkdir()
    rows, samples, msrd = [], [], []
    noise = {1: -2.0, 2: -1.0, 3: 0.0, 4: 1.0, 5: 2.0}   # IQR of θ_end: 2
    for seed in range(1, 6):
        for preset in ("draft", "standard"):
            jid = f"j-{preset}-{seed}"
            failed = preset == "draft" and seed == failed_seed
            rows.append({"run": len(rows), "numerics.preset": preset, "seed": seed,
                         "job_id": jid, "state": "failed" if failed else "succeeded",
                         "failure_kind": "volume-drift" if failed else "", "eq1_ok": 0,
                         "mixing_time_s": 7200,
                         # draft redoes seed steps; the result volume_error_max is the end
                         # value, which the summary must not take for the run's largest
                         "steps_rejected": seed if preset == "draft" else 0,
                         "volume_error_max": 0.001})
            for t in range(0, 7201, 600):
                theta = 40 + 5 * t / 3600 + noise[seed] + (shift_theta if preset == "draft"
                                                           else 0)
                # the volume error peaks mid-run: 1 % × seed for draft at t = 3600 s
                vol = (0.01 * seed if preset == "draft" else 0.005) if t == 3600 else 0.002
                samples.append([jid, t, theta, 5.3 + 0.01 * seed, 1.0 + 0.1 * seed, 3.0, vol])
            for lag in (60, 600, 3600, 7200):
                # MSRD at the end / r²: 0.5 + 0.1·seed, draft 10 % higher (IQR 0.2, Δ ≈ 0.08).
                end = (0.5 + 0.1 * seed) * (1.1 if preset == "draft" else 1.0) * 8.88**2
                msrd.append([jid, lag, end * lag / 7200])
    _write_data(d, rows, samples, msrd)
    return f, d


def test_fitness_report_on_synthetic_data_with_known_answers(tmp_path):
    f, d = _synthetic(tmp_path, shift_theta=0.5)
    out = tmp_path / "out"
    r = _run(["report", str(f), "--from-data", str(d), "--out", str(out)])
    assert r.returncode == 0, r.stderr
    fit = pd.read_csv(out / "fitness.csv").set_index("metric")
    # θ at the end: Δ = 0.5 against IQR 2 → fit; shape index: identical → fit.
    assert fit.loc["theta_end_deg", "diff"] == pytest.approx(0.5)
    assert fit.loc["theta_end_deg", "iqr"] == pytest.approx(2.0)
    assert fit.loc["theta_end_deg", "fit"] == "yes"
    assert fit.loc["shape_index_end", "diff"] == pytest.approx(0.0)
    # MSRD/r² at the end: medians 0.8 and 0.88 (Δ 0.08), IQRs 0.2 and 0.22 → 0.08 < 0.105: fit.
    assert fit.loc["msrd_end_over_r2", "diff"] == pytest.approx(0.08)
    assert fit.loc["msrd_end_over_r2", "fit"] == "yes"
    assert "**fit**" in (out / "fitness.md").read_text()
    assert (out / "synthetic-trends.png").stat().st_size > 0  # a categorical x axis draws

    f2, d2 = _synthetic(tmp_path / "b", shift_theta=1.5, failed_seed=3) if (
        tmp_path / "b").mkdir() is None else None
    out2 = tmp_path / "out2"
    r = _run(["report", str(f2), "--from-data", str(d2), "--out", str(out2)])
    assert r.returncode == 0, r.stderr
    fit = pd.read_csv(out2 / "fitness.csv").set_index("metric")
    # One draft run failed: 4 runs remain (seeds 1, 2, 4, 5: median θ_end shifts by 1.5).
    assert fit.loc["theta_end_deg", "n"] == 4
    assert fit.loc["theta_end_deg", "fit"] == "no"
    assert "**not fit** — theta_end_deg" in (out2 / "fitness.md").read_text()
    summary = pd.read_csv(out2 / "summary.csv").set_index("numerics.preset")
    assert summary.loc["draft", "failed"] == 1
    assert summary.loc["draft", "failures"] == "volume-drift"
    # Numerical health over every run of the point, the failed one included: 1+…+5 steps redone.
    assert summary.loc["draft", "steps_redone"] == 15
    assert summary.loc["draft", "volume_error_peak"] == pytest.approx(0.05)
    assert summary.loc["standard", "steps_redone"] == 0
    assert summary.loc["standard", "volume_error_peak"] == pytest.approx(0.005)
    assert "| 15 | 5 % |" in (out2 / "summary.md").read_text()


def test_theta_and_shape_index_over_the_last_hour_are_the_plateau_the_end_wanders_about(tmp_path):
    study = _alpha_study(tmp_path)
    runs = pd.DataFrame([{"job_id": "long", "state": "succeeded", "cells.alpha": 0.4375},
                         {"job_id": "short", "state": "succeeded", "cells.alpha": 0.6},
                         {"job_id": "lost", "state": "failed", "cells.alpha": 0.6}])
    nan = float("nan")
    rows = []
    # 4 h: θ 90° on its plateau, one NaN sample in the last hour, the last sample a dip to 80°.
    for t in range(0, 14401, 600):
        theta = 80.0 if t == 14400 else (nan if t == 12000 else 90.0)
        rows.append(["long", t, theta, 5.5 if t == 14400 else 5.4, 1.0, 3.0, 0.001])
    # 40 min: the window is its last half (t ≥ 1200 s): 60, 70, 80 → 70.
    for t, theta in ((0, 20.0), (600, 50.0), (1200, 60.0), (1800, 70.0), (2400, 80.0)):
        rows.append(["short", t, theta, 5.4, 1.0, 3.0, 0.001])
    rows += [["lost", t, 50.0, 5.4, 1.0, 3.0, 0.001] for t in (0, 600)]
    samples = pd.DataFrame(rows, columns=["job_id", "t_s"] + st.SAMPLE_COLUMNS)
    msrd = pd.DataFrame(columns=["job_id", "lag_s", "msrd_um2"])
    got = st.derive_metrics(study, runs, samples, msrd).set_index("job_id")
    assert got.loc["long", "theta_end_deg"] == 80.0
    # t ≥ 10 800 s: 10 800, 11 400, 12 600, 13 200, 13 800 at 90°, 14 400 at 80° (12 000 NaN).
    assert got.loc["long", "theta_last_hour_deg"] == pytest.approx((5 * 90 + 80) / 6)
    assert got.loc["short", "theta_last_hour_deg"] == pytest.approx(70.0)
    # The shape index's window is the same, its NaN-free samples all seven (one at 5.5).
    assert got.loc["long", "shape_index_end"] == 5.5
    assert got.loc["long", "shape_index_last_hour"] == pytest.approx((6 * 5.4 + 5.5) / 7)
    assert math.isnan(got.loc["lost", "theta_last_hour_deg"])  # a failed run has no plateau
    assert {"theta_last_hour_deg", "shape_index_last_hour"} <= set(st.FITNESS_METRICS)


def test_the_mixing_time_less_the_turn_is_shown_only_where_a_run_reports_it(tmp_path):
    study = _alpha_study(tmp_path)
    samples = pd.DataFrame(columns=["job_id", "t_s"] + st.SAMPLE_COLUMNS)
    msrd = pd.DataFrame(columns=["job_id", "lag_s", "msrd_um2"])
    old = pd.DataFrame([{"job_id": j, "state": "succeeded", "cells.alpha": a,
                         "mixing_time_s": 5000.0} for j, a in (("a", 0.4375), ("b", 0.6))])
    runs = st.derive_metrics(study, old, samples, msrd)
    table = st.summary_table(study, runs)
    assert "mixing_time_less_rotation_s_median" not in table
    assert st.METRICS["mixing_time_less_rotation_s"] not in st.summary_markdown(study, table)
    new = old.assign(mixing_time_less_rotation_s=[7000.0, 9000.0],
                     state=["succeeded", "failed"])
    runs = st.derive_metrics(study, new, samples, msrd)
    # A failed run's value is not counted, as for every metric.
    assert math.isnan(runs.set_index("job_id").loc["b", "mixing_time_less_rotation_s"])
    table = st.summary_table(study, runs).set_index("cells.alpha")
    assert table.loc[0.4375, "mixing_time_less_rotation_s_median"] == 7000.0
    assert table.loc[0.4375, "mixing_time_less_rotation_s_n"] == 1
    md = st.summary_markdown(study, table.reset_index())
    assert st.METRICS["mixing_time_less_rotation_s"] in md and "7e+03 [7e+03, 7e+03] (1)" in md


def test_an_eq1_fit_longer_than_its_run_is_not_counted_and_is_listed(tmp_path):
    # fig8's p_a r/2γ = 0.33, α = 0.75 seed 2: θ rising 36° → 83° over 6 h, Eq. 1 "converged" at
    # θ_eq = 138°, τ_f = 44 442 s — an extrapolation the engine's fit accepts (τ_f ≤ 10× span).
    study = _alpha_study(tmp_path)
    runs = pd.DataFrame([
        {"job_id": "slow", "state": "succeeded", "cells.alpha": 0.6, "seed": 2, "eq1_ok": 1,
         "theta_eq_deg": 138.2, "tau_f_s": 44442.0, "t_end_s": 21600.0},
        {"job_id": "edge", "state": "succeeded", "cells.alpha": 0.6, "seed": 3, "eq1_ok": 1,
         "theta_eq_deg": 95.0, "tau_f_s": 21600.0, "t_end_s": 21600.0},
        {"job_id": "fast", "state": "succeeded", "cells.alpha": 0.4375, "seed": 1, "eq1_ok": 1,
         "theta_eq_deg": 90.0, "tau_f_s": 2000.0, "t_end_s": 21600.0},
        {"job_id": "flat", "state": "succeeded", "cells.alpha": 0.4375, "seed": 2, "eq1_ok": 0,
         "theta_eq_deg": float("nan"), "tau_f_s": float("nan"), "t_end_s": 21600.0}])
    samples = pd.DataFrame(columns=["job_id", "t_s"] + st.SAMPLE_COLUMNS)
    msrd = pd.DataFrame(columns=["job_id", "lag_s", "msrd_um2"])
    got = st.derive_metrics(study, runs, samples, msrd).set_index("job_id")
    assert math.isnan(got.loc["slow", "theta_eq_deg"]) and math.isnan(got.loc["slow", "tau_f_s"])
    assert math.isnan(got.loc["slow", "tau_f_over_tau_p"])
    assert got.loc["edge", "theta_eq_deg"] == 95.0  # τ_f equal to the run: 1 − 1/e seen
    assert got.loc["fast", "tau_f_s"] == 2000.0
    assert list(got["eq1_beyond_run"]) == [True, False, False, False]
    md = st.unsaturated_fits_markdown(study, got.reset_index())
    assert "cells.alpha = 0.6, seed 2: τ_f = 44442 s against a 21600 s run, θ_eq = 138.2°" in md
    assert "seed 3" not in md and "seed 1" not in md
    assert st.unsaturated_fits_markdown(study, got.reset_index().iloc[1:]) == ""


# ---- jobs to runs: foamd's engine reads both -------------------------------------------------

def _cancel_all(client, tag):
    """Cancels a tag's jobs and waits (up to a minute) until none runs: they are matched, not
    run."""
    for j in client.job_infos(tag=tag):
        client.cancel(j.id, "test: matched, not run")
    deadline = time.monotonic() + 60
    while any(not j.terminal for j in client.job_infos(tag=tag)) and time.monotonic() < deadline:
        time.sleep(0.2)


def test_runs_on_reduced_keys_find_their_jobs_and_a_refused_run_names_its_key(foamd, client,
                                                                               tmp_path):
    # foamd resolves the reduced keys (p_a r/2γ, τ_γ, L_η/r) into p_a, η, ξ and stores them as
    # null: a run on a reduced key must still find its job, or a rerun would submit it again.
    (tmp_path / "base.toml").write_text(BASE)
    f = tmp_path / "reduced.toml"
    f.write_text(textwrap.dedent("""\
        [study]
        name = "reduced"
        base = "base.toml"
        seeds = [7]
        [spec]
        duration_s = 240
        "cells.tau_gamma_s" = 10
        "cells.l_eta_reduced" = 0.5
        [[grid]]
        "cells.pa_reduced" = [0.2, 0.33]
        """))
    study = st.load(f)
    assert st.submit_missing(study, client) == (2, 0)
    _cancel_all(client, study.tag)
    found, _, stale = matching._run_jobs(study, client)
    assert sorted(found) == [0, 1] and not stale
    for i, js in found.items():
        cells = json.loads(js[0].resolved_spec_json)["cells"]
        assert cells["pa_reduced"] is None
        assert cells["p_a"] * cells["radius_mean_um"] / (2 * cells["gamma"]) == pytest.approx(
            study.runs()[i].point["cells.pa_reduced"])
    # A run foamd refuses is no run any job can be: its spec's error names the run and the key.
    bad = tmp_path / "bad.toml"
    bad.write_text(f.read_text().replace("[0.2, 0.33]", "[0.2, 60]"))
    refused = st.load(bad)
    run = refused.runs()[1]
    with pytest.raises(st.StudyError, match=r"cells\.pa_reduced=60, seed 7: .*cells\.pa_reduced"):
        matching._run_spec(refused, client, refused.settings(run), run.label())
    with pytest.raises(ValueError, match=r"cells\.alpha"):
        client.resolve({"scene": "fusion", "cells.alpha": 1.5})


def _as_an_earlier_version_wrote_it(spec):
    """A record of the version before numerics.contact_law, numerics.remesh_on_surface,
    numerics.remesh_keep_out_um and scene.polarity_from_preparation: the law named by its two
    switches, the others absent (the runs of then ran as the study pins them)."""
    n = spec["numerics"]
    law = n.pop("contact_law")
    n["contact_within_prisms"] = law != "supplement"
    n["contact_prisms_overlap_only"] = law == "prisms-overlap"
    assert n.pop("remesh_on_surface") is False and n.pop("remesh_keep_out_um") == 0
    assert spec["scene"].pop("polarity_from_preparation") is False
    return spec


def test_an_earlier_versions_records_are_their_runs_and_no_key_may_differ(tmp_path):
    import sqlite3
    import types
    from activefoam import Client
    from activefoam.client import flatten
    from conftest import Foamd
    (tmp_path / "base.toml").write_text(BASE)
    f = tmp_path / "old.toml"
    pins = ('"numerics.remesh_on_surface" = false\n'
            '"scene.polarity_from_preparation" = false\n')
    text = textwrap.dedent("""\
        [study]
        name = "old"
        base = "base.toml"
        seeds = [1]
        [spec]
        duration_s = 240
        PINS[[grid]]
        "cells.alpha" = [0.4375, 0.6]
        [[diagnose]]
        name = "same-step"
        spec = { "numerics.dt_s" = 0.5 }
        [[diagnose]]
        name = "reference-step"
        spec = { "numerics.dt_s" = 0.25 }
        """)
    f.write_text(text.replace("PINS", pins))
    study = st.load(f)
    d = Foamd(tmp_path)
    try:
        with Client(d.address) as c:
            assert st.submit_missing(study, c) == (2, 0)
            _cancel_all(c, study.tag)
    finally:
        d.stop()
    # The store as an earlier version left it: each job's record in that version's keys.
    con = sqlite3.connect(str(tmp_path / "foamd.db"))
    with con:
        for jid, record in con.execute("SELECT id, spec_json FROM jobs").fetchall():
            old = json.dumps(_as_an_earlier_version_wrote_it(json.loads(record)))
            con.execute("UPDATE jobs SET spec_json = ? WHERE id = ?", (old, jid))
    con.close()

    d = Foamd(tmp_path)
    try:
        with Client(d.address) as c:
            jobs = c.job_infos(tag=study.tag)
            assert len(jobs) == 2
            for j in jobs:
                assert "contact_within_prisms" in j.spec_json   # kept as stored
                now = json.loads(j.resolved_spec_json)
                assert now["numerics"]["contact_law"] == "prisms-overlap"
                assert "contact_within_prisms" not in now["numerics"]
            found, _, stale = matching._run_jobs(study, c)
            assert sorted(found) == [0, 1] and not stale
            for i, js in found.items():
                assert json.loads(js[0].resolved_spec_json)["cells"]["alpha"] == \
                    study.runs()[i].point["cells.alpha"]
            # The same study at today's defaults of the keys added since (remeshing on the
            # surface, polarities from the preparation), or at another contact law: other runs.
            for name, variant in (("defaults", text.replace("PINS", "")),
                                  ("law", text.replace("PINS", pins + '"numerics.contact_law"'
                                                       ' = "prisms"\n'))):
                (tmp_path / f"{name}.toml").write_text(variant)
                other = st.load(tmp_path / f"{name}.toml")
                found, _, stale = matching._run_jobs(other, c)
                assert not found and len(stale) == 2, name
            # A diagnosis that changes nothing the run had is no rerun; one that does is.
            run, found_job = study.runs()[0], matching._run_jobs(study, c)[0][0][0]
            same, reference = study.diagnoses
            assert matching._diag_is_noop(study, c, run, same, found_job)
            assert not matching._diag_is_noop(study, c, run, reference, found_job)

            # Any one key of the record other than a label, changed: not the run.
            resolved = matching._run_spec(study, c, study.settings(run), run.label())
            assert "numerics.preset" in resolved.labels
            record = json.loads(found_job.resolved_spec_json)
            keys = list(flatten(record))
            assert len(keys) > 50
            for key in keys:
                changed = json.loads(found_job.resolved_spec_json)
                node = changed
                *path, leaf = key.split(".")
                for p in path:
                    node = node[p]
                v = node[leaf]
                node[leaf] = (not v if isinstance(v, bool) else v * 2 + 1
                              if isinstance(v, (int, float)) else v + "-other"
                              if isinstance(v, str) else 1.0)
                fake = types.SimpleNamespace(id="x", seed=found_job.seed, created_utc="",
                                             resolved_spec_json=json.dumps(changed))
                hit, stale = matching._jobs_by_run(study, c, [fake])
                assert bool(hit) == (key in resolved.labels), key
    finally:
        d.stop()


def test_fitness_judges_a_candidate_of_a_second_grid_against_the_first_grids_reference(tmp_path):
    """Δt 0.5 (grid 1) and Δt 1 with ε_CG 1e-2 (grid 2) are both judged against the Δt 0.25
    runs of grid 1; the two candidates' verdicts are their own (Δt 0.5 fit, Δt 1 not)."""
    f = tmp_path / "scheme.toml"
    f.write_text(textwrap.dedent("""\
        [study]
        name = "scheme"
        seeds = [1, 2, 3, 4, 5]
        x = "numerics.dt_s"
        [spec]
        scene = "fusion"
        duration_s = 7200
        [[grid]]
        "numerics.dt_s" = [0.25, 0.5]
        [[grid]]
        "numerics.dt_s" = [1.0]
        "numerics.cg_tol" = [0.01]
        [fitness]
        key = "numerics.dt_s"
        reference = 0.25
        metrics = ["theta_end_deg"]
        """))
    d = tmp_path / "data"
    d.mkdir()
    rows, samples, msrd = [], [], []
    noise = {1: -2.0, 2: -1.0, 3: 0.0, 4: 1.0, 5: 2.0}   # IQR of θ_end: 2
    shift = {0.25: 0.0, 0.5: 0.4, 1.0: 3.0}
    for seed in range(1, 6):
        for dt, tol in ((0.25, None), (0.5, None), (1.0, 0.01)):
            jid = f"j-{dt}-{seed}"
            row = {"run": len(rows), "numerics.dt_s": dt, "seed": seed, "job_id": jid,
                   "state": "succeeded", "failure_kind": "", "eq1_ok": 0,
                   "mixing_time_s": 7200}
            if tol is not None:
                row["numerics.cg_tol"] = tol
            rows.append(row)
            for t in range(0, 7201, 600):
                theta = 40 + 5 * t / 3600 + noise[seed] + shift[dt]
                samples.append([jid, t, theta, 5.3, 1.0, 3.0, 0.002])
            msrd += [[jid, lag, 40.0 * lag / 7200] for lag in (60, 600, 7200)]
    _write_data(d, rows, samples, msrd)
    out = tmp_path / "out"
    r = _run(["report", str(f), "--from-data", str(d), "--out", str(out)])
    assert r.returncode == 0, r.stderr
    fit = pd.read_csv(out / "fitness.csv").set_index("candidate")
    assert set(fit.index) == {"numerics.dt_s = 0.5", "numerics.dt_s = 1.0, numerics.cg_tol = 0.01"}
    half = fit.loc["numerics.dt_s = 0.5"]
    assert half["n_ref"] == 5 and half["n"] == 5
    assert half["diff"] == pytest.approx(0.4)
    assert half["fit"] == "yes"
    one = fit.loc["numerics.dt_s = 1.0, numerics.cg_tol = 0.01"]
    assert one["n_ref"] == 5 and one["n"] == 5   # the Δt 0.25 runs, not the 0.5 ones
    assert one["diff"] == pytest.approx(3.0)
    assert one["fit"] == "no"
    md = (out / "fitness.md").read_text()
    assert "`numerics.dt_s = 0.5`: **fit**" in md
    assert "`numerics.dt_s = 1.0, numerics.cg_tol = 0.01`: **not fit** — theta_end_deg" in md
    # The calibrated reading. Both settings ran seeds 1–5: each seed's two runs are swapped or
    # not (2^5 relabellings). θ_end at 1 s is the 0.25 s run's + 3 for every seed, so the
    # observed labelling and its mirror are the farthest (mean difference 3), and 32
    # relabellings cannot show a difference at 5 %: p = 2/32, and the report says why.
    cal = pd.read_csv(out / "fitness-calibration.csv").set_index("candidate")
    one = cal.loc["numerics.dt_s = 1.0, numerics.cg_tol = 0.01"]
    assert bool(one["paired"]) and one["relabellings"] == 32
    assert one["p_value"] == pytest.approx(2 / 32) and one["smallest_p"] == pytest.approx(2 / 32)
    assert one["worst_ratio"] == pytest.approx(3.0) and one["most_different"] == "theta_end_deg"
    assert cal.loc["numerics.dt_s = 0.5", "worst_ratio"] == pytest.approx(0.4)
    assert "none could be: the smallest p 32 relabellings allow is 0.0625" in md
    assert "The rule's reading" in md
    # Seed by seed: every seed's 1 s run is its 0.25 s run + 3, the 0.5 s run + 0.4.
    paired = pd.read_csv(out / "fitness-paired.csv").set_index("candidate")
    one = paired.loc["numerics.dt_s = 1.0, numerics.cg_tol = 0.01"]
    assert one["metric"] == "theta_end_deg" and one["pairs"] == 5
    assert one["paired_diff"] == pytest.approx(3.0) and one["paired_lo"] == pytest.approx(3.0)
    assert one["coverage"] == pytest.approx(30 / 32)
    assert one["sd_diff"] == pytest.approx(0.0, abs=1e-9)
    assert math.isinf(one["found_80"])   # five pairs cannot reach p < 0.05: nothing is found
    assert one["higher"] == 5 and one["lower"] == 0
    assert paired.loc["numerics.dt_s = 0.5", "paired_diff"] == pytest.approx(0.4)
    assert "## Seed by seed" in md


def test_a_failed_reference_leaves_its_seed_out_and_the_rest_are_read_in_pairs(tmp_path):
    """Step fitness's design: 10 seeds a side, the
    reference of seed 6 failed in the simulation. The calibrated test relabels within the 9 seed
    pairs both sides ended (2^9), the candidate's unpartnered seed 6 left out; the failure is
    listed with its kind and time. With 5 shared seeds it splits all the runs, as before."""
    f = tmp_path / "step.toml"
    f.write_text(textwrap.dedent("""\
        [study]
        name = "step"
        seeds = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]
        x = "numerics.dt_s"
        [spec]
        scene = "fusion"
        duration_s = 7200
        [[grid]]
        "numerics.dt_s" = [0.25, 1.0]
        [fitness]
        key = "numerics.dt_s"
        reference = 0.25
        metrics = ["theta_end_deg", "shape_index_end"]
        """))

    def write(d, ref_seeds, shift):
        d.mkdir()
        rows, samples, msrd = [], [], []
        for dt in (0.25, 1.0):
            for seed in range(1, 11):
                if dt == 0.25 and seed not in ref_seeds:
                    continue
                jid = f"j-{dt}-{seed}"
                failed = dt == 0.25 and seed == 6
                rows.append({"run": len(rows), "numerics.dt_s": dt, "seed": seed, "job_id": jid,
                             "state": "failed" if failed else "succeeded",
                             "failure_kind": "volume-drift" if failed else "",
                             "t_end_s": 5573.5 if failed else 7200.0, "eq1_ok": 0,
                             "mixing_time_s": 7200})
                # Seeds spread by 3° (i·3), far more than the step's shift: only pairs see it.
                for t in range(0, 7201 if not failed else 5401, 600):
                    theta = 40 + 5 * t / 3600 + 3.0 * seed + (shift * (1 + 0.01 * seed)
                                                              if dt == 1.0 else 0.0)
                    samples.append([jid, t, theta, 5.3 + 0.01 * seed, 1.0, 3.0, 0.002])
                msrd += [[jid, lag, 40.0 * lag / 7200] for lag in (60, 600, 7200)]
        _write_data(d, rows, samples, msrd)

    write(tmp_path / "data", set(range(1, 11)), shift=1.0)
    out = tmp_path / "out"
    r = _run(["report", str(f), "--from-data", str(tmp_path / "data"), "--out", str(out)])
    assert r.returncode == 0, r.stderr
    cal = pd.read_csv(out / "fitness-calibration.csv").iloc[0]
    assert cal["n_ref"] == 9 and cal["n"] == 10
    assert cal["n_relabelled_ref"] == 9 and cal["n_relabelled"] == 9
    assert bool(cal["paired"]) and cal["relabellings"] == 2 ** 9
    # Every pair moved θ up by about 1°, against a 3° spread a seed: found within pairs only.
    # The shape index is the same on both sides: θ alone, its extreme labelling and the mirror.
    assert cal["p_value"] == pytest.approx(2 / 512)
    md = (out / "fitness.md").read_text()
    assert "the 9 seeds both sides ended, 0 reference and 1 candidate runs without a partner" in md
    assert "- reference `numerics.dt_s = 0.25`: 1 failed — seed 6 (volume-drift at 5 574 s)" in md
    paired = pd.read_csv(out / "fitness-paired.csv")
    assert set(paired["pairs"]) == {9} and paired["found_80"].notna().all()

    # References of seeds 1–5 and 6 only (6 failed): 5 shared seeds cannot reach p < 0.05 in
    # pairs, so all 15 runs are split (C(15, 5)), the earlier reading.
    write(tmp_path / "five", {1, 2, 3, 4, 5, 6}, shift=1.0)
    out5 = tmp_path / "out5"
    r = _run(["report", str(f), "--from-data", str(tmp_path / "five"), "--out", str(out5)])
    assert r.returncode == 0, r.stderr
    cal = pd.read_csv(out5 / "fitness-calibration.csv").iloc[0]
    assert not bool(cal["paired"]) and cal["relabellings"] == math.comb(15, 5)
    assert cal["n_relabelled_ref"] == 5 and cal["n_relabelled"] == 10


# ---- shared runs: a point two studies have in common runs once --------------------------------

class _FakeJob:
    def __init__(self, jid, seed, spec, state="SUCCEEDED", failure_kind=""):
        from activefoam.v1 import job_pb2
        self.id, self.seed, self.spec_json = jid, seed, json.dumps(spec)
        self.resolved_spec_json = self.spec_json   # as an engine of today's keys stored it
        self.created_utc = jid
        self.state = job_pb2.JobState.Value("JOB_STATE_" + state)
        self.failure_kind, self.progress = failure_kind, 1.0


class _FakeFoamd:
    """What the study code asks of foamd: jobs by tag; SubmitJob; and ResolveSpec, which resolves
    a spec the way foamd does for these keys: the defaults (α = 0.4375, τ_p = 600 s unless the
    base sets them; `derived`, keys computed from the others as the engine derives τ_r from the
    cells), the settings on top, numerics.preset a label."""

    def __init__(self, defaults, derived=None):
        self.jobs, self.submitted, self.defaults = {}, [], defaults
        self.derived = derived or {}

    def add(self, tag, job):
        self.jobs.setdefault(tag, []).append(job)

    def job_infos(self, tag):
        return list(self.jobs.get(tag, []))

    def spec(self, overrides):
        from activefoam.client import setting
        spec = {"cells": dict(self.defaults), "numerics": {"remesh_on_surface": True},
                "scene": {"polarity_from_preparation": True}}
        for s in (setting(k, v) for k, v in overrides.items()):
            k, v = s.split("=", 1)
            node = spec
            *path, leaf = k.split(".")
            for p in path:
                node = node.setdefault(p, {})
            node[leaf] = (json.loads(v) if v[0].isdigit() or v[0] == "-" or v in ("true", "false")
                          else v)
        for k, f in self.derived.items():
            table, leaf = k.split(".")
            spec[table].setdefault(leaf, f(spec))
        return spec

    def cancel(self, jid, reason=""):
        from activefoam.v1 import job_pb2
        for j in (j for js in self.jobs.values() for j in js if j.id == jid):
            j.state = job_pb2.JobState.Value("JOB_STATE_CANCELLED")
        return "cancelled"

    def resolve(self, base, overrides):
        class R:
            spec_json, labels = json.dumps(self.spec(overrides)), ["numerics.preset"]
        return R()

    def submit(self, base, tags, priority, idempotency_key, overrides):
        from activefoam.client import setting
        spec = self.spec(overrides)
        (tag,) = tags
        jid = f"j-{len(self.submitted):04d}"
        self.add(tag, _FakeJob(jid, spec["seed"], spec, state="QUEUED"))
        self.submitted.append(dict(setting(k, v).split("=", 1) for k, v in overrides.items()))
        self.submitted[-1]["tag"] = tag
        self.submitted[-1]["key"] = idempotency_key

        class R:
            created, id = True, jid
        return R()


def _shared_studies(tmp: Path, base_alpha_line=""):
    (tmp / "base.toml").write_text('scene = "fusion"\n' + base_alpha_line)
    common = '[spec]\nduration_s = 240\n'
    (tmp / "alpha.toml").write_text(textwrap.dedent("""\
        [study]
        name = "alpha"
        base = "base.toml"
        seeds = [1, 2]
        """) + common + '[[grid]]\n"cells.alpha" = [0.4375, 0.6]\n')
    (tmp / "taup.toml").write_text(textwrap.dedent("""\
        [study]
        name = "taup"
        base = "base.toml"
        seeds = [1, 2]
        """) + common + textwrap.dedent("""\
        [[grid]]
        "cells.tau_p_s" = [150, 600]
        [[share]]
        file = "alpha.toml"
        this = { "cells.tau_p_s" = 600 }
        that = { "cells.alpha" = 0.4375 }
        """))
    return st.load(tmp / "taup.toml")


def _alpha_jobs(foamd, states=("SUCCEEDED", "SUCCEEDED"), tau_p=600):
    for seed, state in zip((1, 2), states):
        for a in (0.4375, 0.6):
            spec = {"seed": seed, "duration_s": 240, "cells": {"alpha": a, "tau_p_s": tau_p},
                    "numerics": {"remesh_on_surface": True},  # as today's foamd echoes it
                    "scene": {"polarity_from_preparation": True}}
            foamd.add("study:alpha", _FakeJob(f"j-a{a}-{seed}", seed, spec, state=state))



def test_a_shared_point_takes_the_other_studys_job_and_is_not_run_again(tmp_path):
    taup = _shared_studies(tmp_path)
    foamd = _FakeFoamd({"alpha": 0.4375, "tau_p_s": 600})
    _alpha_jobs(foamd)
    n, held = st.submit_missing(taup, foamd)
    # τ_p = 150 at both seeds runs; τ_p = 600 is the α study's α = 0.4375 run of each seed.
    assert (n, held) == (2, 2)
    assert sorted(s["cells.tau_p_s"] for s in foamd.submitted) == ["150", "150"]
    found, source, _ = matching._run_jobs(taup, foamd)
    shared = [i for i, r in enumerate(taup.runs()) if r.point["cells.tau_p_s"] == 600]
    assert sorted(source) == shared and set(source.values()) == {"alpha"}
    assert [found[i][0].id for i in shared] == ["j-a0.4375-1", "j-a0.4375-2"]
    # Rerun: nothing new.
    assert st.submit_missing(taup, foamd) == (0, 4)


def test_a_shared_run_whose_job_was_cancelled_is_submitted_as_the_other_studys(tmp_path):
    taup = _shared_studies(tmp_path)
    foamd = _FakeFoamd({"alpha": 0.4375, "tau_p_s": 600})
    _alpha_jobs(foamd, states=("SUCCEEDED", "CANCELLED"))
    n, _ = st.submit_missing(taup, foamd)
    assert n == 3
    # τ_p = 150 as this study's; τ_p = 600 of seed 2 is α's run, its second attempt.
    assert sorted((s["tag"], s.get("cells.tau_p_s"), s.get("cells.alpha"), s["seed"])
                  for s in foamd.submitted) == [
        ("study:alpha", None, "0.4375", "2"),
        ("study:taup", "150", None, "1"), ("study:taup", "150", None, "2")]
    assert next(s["key"] for s in foamd.submitted if s["tag"] == "study:alpha").endswith(":1")
    found, source, _ = matching._run_jobs(taup, foamd)
    shared = [i for i, r in enumerate(taup.runs()) if r.point["cells.tau_p_s"] == 600]
    assert all(source[i] == "alpha" for i in shared)


def test_cancelled_jobs_are_no_failed_attempts(tmp_path):
    """A run whose jobs were cancelled five times (a study moved to another step, a queue
    reordered) is submitted again with a fresh key; one whose jobs failed five times is not."""
    _shared_studies(tmp_path)
    alpha = st.load(tmp_path / "alpha.toml")
    foamd = _FakeFoamd({"alpha": 0.4375, "tau_p_s": 600})
    for seed in (1, 2):
        for a, state, kind in ((0.4375, "CANCELLED", ""), (0.6, "FAILED", "engine-error")):
            spec = {"seed": seed, "duration_s": 240, "cells": {"alpha": a, "tau_p_s": 600},
                    "numerics": {"remesh_on_surface": True},
                    "scene": {"polarity_from_preparation": True}}
            for k in range(st.MAX_ATTEMPTS):
                foamd.add("study:alpha", _FakeJob(f"j-{a}-{seed}-{k}", seed, spec, state=state,
                                                  failure_kind=kind))
    out = io.StringIO()
    assert st.submit_missing(alpha, foamd, out=out) == (2, 2)
    assert sorted((s["cells.alpha"], s["seed"]) for s in foamd.submitted) == [
        ("0.4375", "1"), ("0.4375", "2")]
    assert all(s["key"].endswith(f":{st.MAX_ATTEMPTS}") for s in foamd.submitted)
    assert out.getvalue().count(f"{st.MAX_ATTEMPTS} attempts failed; not submitted again") == 2


def test_a_shared_run_submitted_before_its_owner_is_the_owners_and_runs_once(tmp_path):
    # The borrowing study is submitted first, the α study not yet at all: the shared runs go in
    # as α's runs, and the α study then submits only what else it has (α = 0.6).
    taup = _shared_studies(tmp_path)
    alpha = st.load(tmp_path / "alpha.toml")
    foamd = _FakeFoamd({"alpha": 0.4375, "tau_p_s": 600})
    assert st.submit_missing(taup, foamd) == (4, 0)
    assert sorted((s["tag"], s["seed"]) for s in foamd.submitted) == [
        ("study:alpha", "1"), ("study:alpha", "2"), ("study:taup", "1"), ("study:taup", "2")]
    assert st.submit_missing(alpha, foamd) == (2, 2)
    assert sorted(s["cells.alpha"] for s in foamd.submitted[4:]) == ["0.6", "0.6"]
    # Each study sees every one of its runs once, and nothing more is submitted.
    for study in (taup, alpha):
        found, _, stale = matching._run_jobs(study, foamd)
        assert sorted(found) == list(range(len(study.runs()))) and not stale
        assert all(len(js) == 1 for js in found.values())
        assert st.submit_missing(study, foamd) == (0, 4)


def test_a_shared_run_whose_own_job_was_cancelled_takes_the_other_studys_job(tmp_path):
    # τ_p = 600 was submitted as this study's own while the α study's jobs were being
    # resubmitted, then cancelled: the α study's jobs are its runs again, nothing is submitted.
    taup = _shared_studies(tmp_path)
    foamd = _FakeFoamd({"alpha": 0.4375, "tau_p_s": 600})
    _alpha_jobs(foamd)
    for seed in (1, 2):
        for tau, state in ((150, "SUCCEEDED"), (600, "CANCELLED")):
            spec = {"seed": seed, "duration_s": 240, "cells": {"alpha": 0.4375, "tau_p_s": tau},
                    "numerics": {"remesh_on_surface": True},
                    "scene": {"polarity_from_preparation": True}}
            foamd.add("study:taup", _FakeJob(f"j-t{tau}-{seed}", seed, spec, state=state))
    assert st.submit_missing(taup, foamd) == (0, 4)
    found, source, _ = matching._run_jobs(taup, foamd)
    shared = [i for i, r in enumerate(taup.runs()) if r.point["cells.tau_p_s"] == 600]
    assert [found[i][0].id for i in shared] == ["j-a0.4375-1", "j-a0.4375-2"]
    assert all(source[i] == "alpha" for i in shared)


def test_a_share_whose_runs_differ_is_an_error_naming_the_key(tmp_path):
    # This study's base gives another α than the shared point's: foamd resolves the two runs
    # differently, whether the other study has run it or not; nothing is left submitted.
    taup = _shared_studies(tmp_path)
    message = (r"share\[0\]: cells\.alpha is 0\.5 in this study's run cells\.tau_p_s=600, "
               r"seed 1 but 0\.4375 in alpha's run cells\.alpha=0\.4375, seed 1: not one run")
    for has_run in (True, False):
        foamd = _FakeFoamd({"alpha": 0.5, "tau_p_s": 600})
        if has_run:
            _alpha_jobs(foamd)
        with pytest.raises(st.StudyError, match=message):
            st.submit_missing(taup, foamd)
        from activefoam.client import state_name
        assert all(state_name(j.state) == "cancelled" for js in foamd.jobs.values() for j in js
                   if j.id.startswith("j-0")), "a job this call submitted was left queued"


def test_another_studys_jobs_of_other_values_are_not_the_shared_run(tmp_path):
    # The α study's jobs ran τ_p 300 s (say, an earlier version of its spec): they are no run of
    # α as it is now, so the shared point has no job yet and goes in as α's run.
    taup = _shared_studies(tmp_path)
    foamd = _FakeFoamd({"alpha": 0.4375, "tau_p_s": 600})
    _alpha_jobs(foamd, tau_p=300)
    assert st.submit_missing(taup, foamd) == (4, 0)
    assert sorted((s["tag"], s.get("cells.tau_p_s"), s["seed"]) for s in foamd.submitted) == [
        ("study:alpha", None, "1"), ("study:alpha", None, "2"),
        ("study:taup", "150", "1"), ("study:taup", "150", "2")]
    _, stale = matching._jobs_by_run(st.load(tmp_path / "alpha.toml"), foamd,
                                     foamd.job_infos("study:alpha"))
    assert sorted(j.id for j in stale) == ["j-a0.4375-1", "j-a0.4375-2", "j-a0.6-1", "j-a0.6-2"]


def _split_share_studies(tmp: Path):
    """τ_p's 600 s point is α's run at seeds 1–2 and β's (α's twin with seed 3) at seed 3."""
    _shared_studies(tmp)
    (tmp / "beta.toml").write_text((tmp / "alpha.toml").read_text().replace(
        'name = "alpha"', 'name = "beta"').replace("seeds = [1, 2]", "seeds = [3]"))
    text = (tmp / "taup.toml").read_text().replace("seeds = [1, 2]", "seeds = [1, 2, 3]")
    (tmp / "taup.toml").write_text(text + textwrap.dedent("""\
        seeds = [1, 2]
        [[share]]
        file = "beta.toml"
        this = { "cells.tau_p_s" = 600 }
        that = { "cells.alpha" = 0.4375 }
        seeds = [3]
        """))
    return st.load(tmp / "taup.toml")


def test_a_point_shared_with_two_studies_by_seed_takes_each_ones_job(tmp_path):
    # A study with a seed more than the one it shares its base point with takes that seed's
    # run from a third study that runs it, instead of running it a second time.
    taup = _split_share_studies(tmp_path)
    foamd = _FakeFoamd({"alpha": 0.4375, "tau_p_s": 600})
    _alpha_jobs(foamd)
    spec = {"seed": 3, "duration_s": 240, "cells": {"alpha": 0.4375, "tau_p_s": 600},
            "numerics": {"remesh_on_surface": True}, "scene": {"polarity_from_preparation": True}}
    foamd.add("study:beta", _FakeJob("j-b0.4375-3", 3, spec))
    assert st.submit_missing(taup, foamd) == (3, 3)
    assert sorted((s["tag"], s["cells.tau_p_s"], s["seed"]) for s in foamd.submitted) == [
        ("study:taup", "150", "1"), ("study:taup", "150", "2"), ("study:taup", "150", "3")]
    found, source, _ = matching._run_jobs(taup, foamd)
    shared = {taup.runs()[i].seed: (found[i][0].id, source[i]) for i in source}
    assert shared == {1: ("j-a0.4375-1", "alpha"), 2: ("j-a0.4375-2", "alpha"),
                      3: ("j-b0.4375-3", "beta")}
    assert st.submit_missing(taup, foamd) == (0, 6)
    # Neither study has run it yet: each seed goes in as its owner's run.
    foamd = _FakeFoamd({"alpha": 0.4375, "tau_p_s": 600})
    assert st.submit_missing(taup, foamd) == (6, 0)
    assert sorted((s["tag"], s["seed"]) for s in foamd.submitted
                  if s.get("cells.tau_p_s") != "150") == [
        ("study:alpha", "1"), ("study:alpha", "2"), ("study:beta", "3")]
    r = _run(["check", str(tmp_path / "taup.toml")])
    assert r.returncode == 0 and "alpha's cells.alpha=0.4375 at seeds [1, 2]" in r.stdout \
        and "beta's cells.alpha=0.4375 at seeds [3]" in r.stdout, r.stdout + r.stderr


@pytest.mark.parametrize("seeds, message", [
    ("[4]", "share[1].seeds: [4] not in study.seeds [1, 2, 3]"),
    ("[2]", "share[1].seeds: beta does not run seeds [2] (its seeds: [3])"),
    ('"3"', "share[1].seeds: a list of distinct seeds"),
])
def test_bad_share_seeds_exit_2_naming_the_key(tmp_path, seeds, message):
    _split_share_studies(tmp_path)
    f = tmp_path / "taup.toml"
    f.write_text(f.read_text().replace("seeds = [3]\n", f"seeds = {seeds}\n"))
    r = _run(["check", str(f)])
    assert r.returncode == 2 and message in r.stderr, r.stdout + r.stderr


def test_a_point_shared_twice_at_one_seed_is_an_error(tmp_path):
    _split_share_studies(tmp_path)
    f = tmp_path / "taup.toml"
    # The first share covers every seed, so the second's seed 3 is claimed twice.
    f.write_text(f.read_text().replace("seeds = [1, 2]\n[[share]]", "[[share]]"))
    r = _run(["check", str(f)])
    assert r.returncode == 2 and "share[1].this: {'cells.tau_p_s': 600} is shared twice at " \
        "one of seeds [3]" in r.stderr, r.stdout + r.stderr


@pytest.mark.parametrize("share, message", [
    ('file = "nope.toml"\nthis = { "cells.tau_p_s" = 600 }\nthat = { "cells.alpha" = 0.4375 }',
     "share[0].file: study: no such file"),
    ('file = "alpha.toml"\nthis = { "cells.tau_p_s" = 601 }\nthat = { "cells.alpha" = 0.4375 }',
     "share[0].this: {'cells.tau_p_s': 601} is not one of this study's points"),
    ('file = "alpha.toml"\nthis = { "cells.tau_p_s" = 600 }\nthat = { "cells.alpha" = 0.5 }',
     "share[0].that: {'cells.alpha': 0.5} is not one of alpha's points"),
    ('file = "alpha.toml"\nthis = { "cells.tau_p_s" = 600 }', "share[0].that: missing"),
    ('file = "alpha.toml"\nthis = { "cells.tau_p_s" = 600 }\nthat = { "cells.alpha" = 0.4375 }'
     '\nthose = 1', "share[0].those"),
    ('file = "other-spec.toml"\nthis = { "cells.tau_p_s" = 600 }\n'
     'that = { "cells.alpha" = 0.4375 }', "sets other [spec] keys or preset (duration_s)"),
])
def test_bad_shares_exit_2_naming_the_key(tmp_path, share, message):
    _shared_studies(tmp_path)
    (tmp_path / "other-spec.toml").write_text((tmp_path / "alpha.toml").read_text().replace(
        "duration_s = 240", "duration_s = 480"))
    text = (tmp_path / "taup.toml").read_text().split("[[share]]")[0]
    (tmp_path / "taup.toml").write_text(text + "[[share]]\n" + share + "\n")
    r = _run(["check", str(tmp_path / "taup.toml")])
    assert r.returncode == 2, r.stdout + r.stderr
    assert message in r.stderr, r.stderr


# ---- a study continued on another store: the committed data's ended runs count as done ---------

def _alpha_study(tmp: Path, name="alpha"):
    (tmp / "base.toml").write_text('scene = "fusion"\n')
    f = tmp / f"{name}.toml"
    f.write_text(textwrap.dedent(f"""\
        [study]
        name = "{name}"
        base = "base.toml"
        seeds = [1, 2]
        [spec]
        duration_s = 240
        [[grid]]
        "cells.alpha" = [0.4375, 0.6]
        """))
    return st.load(f)


def _earlier_data(tmp: Path, study, stale_settings=False):
    """What `collect` wrote from an earlier store: seed 1 succeeded at both α, seed 2 failed in
    the simulation at α 0.6 and was cancelled at α 0.4375; plus a row of a point the study no
    longer has. With stale_settings, seed 1 at α 0.6 ran another duration."""
    d = tmp / "earlier"
    d.mkdir()
    rows, samples, msrd = [], [], []
    for seed, a, state, kind in ((1, 0.4375, "succeeded", ""), (1, 0.6, "succeeded", ""),
                                 (2, 0.6, "failed", "volume-drift"),
                                 (2, 0.4375, "cancelled", ""), (1, 0.8, "succeeded", "")):
        jid = f"j-old-{a}-{seed}"
        run = st.Run({"cells.alpha": a}, seed)
        settings = study.settings(run)
        if stale_settings and (seed, a) == (1, 0.6):
            settings = dict(settings, duration_s=120)
        rows.append({"run": len(rows), "cells.alpha": a, "seed": seed,
                     "settings": json.dumps(settings, sort_keys=True), "job_id": jid,
                     "state": state, "failure_kind": kind, "theta_deg": 50 + seed})
        samples += [[jid, t, 40 + t / 60, 5.4, 1.0, 3.0, 0.001] for t in (0, 120, 240)]
        msrd += [[jid, lag, 0.1 * lag] for lag in (60, 120)]
    _write_data(d, rows, samples, msrd)
    (d / "collected.json").write_text(json.dumps({"study": study.name}))
    return d


def test_an_earlier_stores_ended_runs_count_as_done_and_are_reported_with_the_stores(tmp_path):
    study = _alpha_study(tmp_path)
    carried = st.carried_runs(study, _earlier_data(tmp_path, study))
    runs = study.runs()
    assert sorted((runs[i].seed, runs[i].point["cells.alpha"]) for i in carried.rows) == [
        (1, 0.4375), (1, 0.6), (2, 0.6)]
    assert set(carried.samples["job_id"]) == {"j-old-0.4375-1", "j-old-0.6-1", "j-old-0.6-2"}
    # Only the cancelled run is submitted on the new store; the failed one is a result.
    foamd = _FakeFoamd({"alpha": 0.4375})
    assert st.submit_missing(study, foamd, carried=carried) == (1, 3)
    assert [(s["seed"], s["cells.alpha"]) for s in foamd.submitted] == [("2", "0.4375")]
    assert st.submit_missing(study, foamd, carried=carried) == (0, 4)
    counts, frac, _ = submission._progress(study, foamd, carried)
    assert counts == {"succeeded": 2, "failed": 1, "queued": 1}
    # --retry-failed runs the carried failure again.
    foamd2 = _FakeFoamd({"alpha": 0.4375})
    assert st.submit_missing(study, foamd2, retry_failed=True, carried=carried) == (2, 2)
    # --retry-failed KINDS reruns only failures of those kinds: the carried one is volume drift.
    foamd3 = _FakeFoamd({"alpha": 0.4375})
    assert st.submit_missing(study, foamd3, retry_failed={"preparation-failed"},
                             carried=carried) == (1, 3)
    foamd4 = _FakeFoamd({"alpha": 0.4375})
    assert st.submit_missing(study, foamd4, retry_failed={"volume-drift", "interpenetration"},
                             carried=carried) == (2, 2)
    # The report's data: the store's job where it has one, the carried rows elsewhere, with
    # their samples and curves; the carried rows say where they came from.
    for jobs in foamd.jobs.values():
        for j in jobs:
            j.reason, j.outcome, j.t_s = "", "", 0.0
    out = st.collect(study, foamd, tmp_path / "report" / "data", carried)
    got = pd.read_csv(out / "runs.csv")
    assert list(got["state"]) == ["succeeded", "succeeded", "queued", "failed"]
    assert got["carried_from"].notna().tolist() == [True, True, False, True]
    assert got.loc[0, "theta_deg"] == 51 and got.loc[3, "failure_kind"] == "volume-drift"
    assert json.loads(got.loc[2, "settings"]) == study.settings(runs[2])
    samples = pd.read_csv(out / "samples.csv.gz")
    assert sorted(set(samples["job_id"])) == ["j-old-0.4375-1", "j-old-0.6-1", "j-old-0.6-2"]
    assert len(pd.read_csv(out / "msrd.csv.gz")) == 6
    assert json.loads((out / "collected.json").read_text())["carried_runs"] == 3
    # That data folder carries the same runs again (its own settings column now).
    again = st.carried_runs(study, out)
    assert sorted(again.rows) == sorted(carried.rows)
    # Collected again from the same runs: the same bytes (gzip without a timestamp).
    time.sleep(1.1)
    out2 = st.collect(study, foamd, tmp_path / "report2" / "data", carried)
    for f in ("runs.csv", "samples.csv.gz", "msrd.csv.gz"):
        assert (out / f).read_bytes() == (out2 / f).read_bytes(), f


def test_carried_rows_that_spelled_out_the_default_step_are_the_runs_that_leave_it(client,
                                                                                  tmp_path):
    # Data written while study files spelled out the figure step, in keys of an earlier version
    # among them (the contact law's and the remesher's switches), are the runs of the file that
    # leaves the step to the default: foamd resolves both to one spec. A row at another step
    # (Δt 0.5 s) is not, and without foamd only the same keys and values are.
    study = _alpha_study(tmp_path)
    d = _earlier_data(tmp_path, study)
    table = pd.read_csv(d / "runs.csv")
    spelled = {"numerics.cg_tol": 0.01, "numerics.contact_within_prisms": True,
               "numerics.contact_prisms_overlap_only": True, "numerics.dt_s": 1.0,
               "numerics.integrator": "contact-implicit-consistent",
               "numerics.max_volume_error": 0.2, "numerics.remesh_rescue": True,
               "numerics.remesh_rebuild": True, "scene.polarity_from_preparation": True}
    settings = []
    for _, row in table.iterrows():
        s = dict(json.loads(row["settings"]), **spelled)
        if (row["seed"], row["cells.alpha"]) == (1, 0.6):
            s["numerics.dt_s"] = 0.5
        settings.append(json.dumps(s, sort_keys=True))
    table["settings"] = settings
    table.to_csv(d / "runs.csv", index=False)
    runs = study.runs()
    assert st.carried_runs(study, d).rows == {}
    carried = st.carried_runs(study, d, client)
    assert sorted((runs[i].seed, runs[i].point["cells.alpha"]) for i in carried.rows) == [
        (1, 0.4375), (2, 0.6)]
    # The report's data keep the settings each carried run recorded, so that what it was made
    # with stays on record; collected again, they carry over again.
    out = st.collect(study, client, tmp_path / "report" / "data", carried)
    got = pd.read_csv(out / "runs.csv")
    kept = got[got["carried_from"].notna()]
    assert len(kept) == 2
    assert all(json.loads(t)["numerics.contact_within_prisms"] is True for t in kept["settings"])
    assert sorted(st.carried_runs(study, out, client).rows) == sorted(carried.rows)
    # Nor is one whose earlier keys name another contact law (the supplement's).
    table.loc[0, "settings"] = json.dumps(dict(json.loads(table.loc[0, "settings"]),
                                               **{"numerics.contact_within_prisms": False}))
    table.to_csv(d / "runs.csv", index=False)
    carried = st.carried_runs(study, d, client)
    assert sorted((runs[i].seed, runs[i].point["cells.alpha"]) for i in carried.rows) == [
        (2, 0.6)]


def test_carried_runs_whose_settings_changed_or_of_another_study_are_not_taken(tmp_path):
    study = _alpha_study(tmp_path)
    carried = st.carried_runs(study, _earlier_data(tmp_path, study, stale_settings=True))
    runs = study.runs()
    assert sorted((runs[i].seed, runs[i].point["cells.alpha"]) for i in carried.rows) == [
        (1, 0.4375), (2, 0.6)]
    (tmp_path / "b").mkdir()
    beta = _alpha_study(tmp_path / "b", name="beta")
    with pytest.raises(st.StudyError, match="holds study 'alpha'"):
        st.carried_runs(beta, tmp_path / "earlier")
    with pytest.raises(st.StudyError, match="runs.csv is missing"):
        st.carried_runs(study, tmp_path / "b")
    # Collected with the base's hash: an edited base file takes none of them.
    out = st.collect(study, _FakeFoamd({"alpha": 0.4375}), tmp_path / "c",
                     st.carried_runs(study, tmp_path / "earlier"))
    assert len(st.carried_runs(study, out).rows) == 2
    (tmp_path / "base.toml").write_text('scene = "fusion"\nduration_s = 100\n')
    assert st.carried_runs(st.load(study.path), out).rows == {}
    r = _run(["report", str(study.path), "--from-data", str(tmp_path / "earlier"),
              "--with-data", str(tmp_path / "earlier")])
    assert r.returncode == 2 and "--with-data: not with --from-data" in r.stderr


def test_found_80_scales_the_pairs_sd_and_is_left_out_when_the_test_did_not_pair(tmp_path,
                                                                                monkeypatch):
    from activefoam.study import power
    f = tmp_path / "pairs.toml"
    f.write_text(textwrap.dedent("""\
        [study]
        name = "pairs"
        seeds = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]
        [spec]
        scene = "fusion"
        [[grid]]
        "numerics.dt_s" = [0.25, 0.5]
        [fitness]
        key = "numerics.dt_s"
        reference = 0.25
        metrics = ["theta_end_deg", "tau_f_s"]
        """))
    study = st.load(f)
    shifts = [0.5, -0.5, 1.0, -1.0, 0.0, 2.0, -2.0, 0.25, -0.25, 0.0]   # SD known exactly
    rows = []
    for seed in range(1, 11):
        for dt in (0.25, 0.5):
            rows.append({"numerics.dt_s": dt, "seed": seed, "theta_end_deg":
                         90 + seed + (shifts[seed - 1] if dt == 0.5 else 0.0),
                         "tau_f_s": 2000.0 + 10 * seed})
    calls = []
    monkeypatch.setattr(power, "paired_detectable_shift",
                        lambda n, metrics: calls.append((n, metrics)) or 1.5)
    runs = pd.DataFrame(rows)
    t = st.fitness_paired(study, runs).set_index("metric")
    sd = float(np.std(shifts, ddof=1))
    assert t.loc["theta_end_deg", "pairs"] == 10 and calls[0] == (10, 2)
    assert t.loc["theta_end_deg", "sd_diff"] == pytest.approx(sd)
    assert t.loc["theta_end_deg", "found_80"] == pytest.approx(1.5 * sd)
    assert t.loc["tau_f_s", "found_80"] == pytest.approx(0.0)
    # Seed 10's candidate has no results: the calibrated test relabels within the 9 pairs both
    # sides ended (with two metrics, 7 pairs or more can reach p < 0.05), so the shift is claimed.
    runs.loc[(runs["seed"] == 10) & (runs["numerics.dt_s"] == 0.5),
             ["theta_end_deg", "tau_f_s"]] = math.nan
    t = st.fitness_paired(study, runs).set_index("metric")
    assert t.loc["theta_end_deg", "pairs"] == 9 and calls[-1] == (9, 2)
    assert t.loc["theta_end_deg", "found_80"] == pytest.approx(1.5 * t.loc["theta_end_deg",
                                                                            "sd_diff"])
    # Seeds 7–10 lack the candidate: 6 pairs cannot reach p < 0.05 on two metrics (4/2⁶), so the
    # test splits the 16 runs freely and no paired shift is claimed, though the pairs are shown.
    runs.loc[(runs["seed"] >= 7) & (runs["numerics.dt_s"] == 0.5),
             ["theta_end_deg", "tau_f_s"]] = math.nan
    t = st.fitness_paired(study, runs).set_index("metric")
    assert t.loc["theta_end_deg", "pairs"] == 6
    assert math.isnan(t.loc["theta_end_deg", "found_80"])


# ---- diagnoses: a failed run rerun with some keys changed -------------------------------------

def _alpha_study_1s(tmp: Path, study_keys: str = "", tables: str = ""):
    """Study "alpha": α 0.4375 and 0.6, seeds 1 and 2, 240 s at Δt 1 s; more [study] keys and
    more tables after its grid."""
    (tmp / "base.toml").write_text('scene = "fusion"\n')
    f = tmp / "alpha.toml"
    f.write_text(textwrap.dedent("""\
        [study]
        name = "alpha"
        base = "base.toml"
        seeds = [1, 2]
        """) + study_keys + textwrap.dedent("""\
        [spec]
        duration_s = 240
        "numerics.dt_s" = 1.0
        [[grid]]
        "cells.alpha" = [0.4375, 0.6]
        """) + textwrap.dedent(tables))
    return st.load(f)


def _diagnosed_study(tmp: Path):
    return _alpha_study_1s(tmp, tables="""\
        [[diagnose]]
        name = "keep-out"
        spec = { "numerics.remesh_keep_out_um" = 0.75 }
        kinds = ["interpenetration"]
        [[diagnose]]
        name = "reference-step"
        spec = { "numerics.dt_s" = 0.25 }
        """)


def _diagnosed_jobs(foamd, **settings):
    """Seed 1 failed at both α (interpenetration at 0.4375, volume drift at 0.6); seed 2
    succeeded. `settings`: more of the study's keys (dotted, "__" for ".")."""
    extra = {k.replace("__", "."): v for k, v in settings.items()}
    for seed in (1, 2):
        for a in (0.4375, 0.6):
            spec = foamd.spec({"duration_s": 240, "numerics.dt_s": 1.0, **extra,
                               "cells.alpha": a, "seed": seed})
            kind = ("" if seed == 2 else "interpenetration" if a == 0.4375 else "volume-drift")
            j = _FakeJob(f"j-{a}-{seed}", seed, spec, state="FAILED" if kind else "SUCCEEDED",
                         failure_kind=kind)
            j.reason, j.outcome, j.t_s = "", "", 100.0 if kind else 240.0
            foamd.add("study:alpha", j)


def test_a_run_that_failed_in_the_simulation_is_rerun_once_per_diagnosis_naming_its_kind(
        tmp_path):
    study = _diagnosed_study(tmp_path)
    assert [d.name for d in study.diagnoses] == ["keep-out", "reference-step"]
    assert study.diagnoses[1].kinds == sorted(st.SIMULATION_FAILURES)
    foamd = _FakeFoamd({"alpha": 0.4375})
    _diagnosed_jobs(foamd)
    out = io.StringIO()
    assert st.submit_missing(study, foamd) == (0, 4)  # failed runs are results
    assert st.submit_diagnoses(study, foamd, out=out) == 3
    # The keep-out only for the interpenetration; the reference step for both failures; each
    # the failed run's keys with the diagnosis's on top, tagged diag:alpha.
    got = sorted((s["cells.alpha"], s["numerics.dt_s"], s.get("numerics.remesh_keep_out_um"))
                 for s in foamd.submitted)
    assert got == [("0.4375", "0.25", None), ("0.4375", "1.0", "0.75"), ("0.6", "0.25", None)]
    assert all(s["tag"] == "diag:alpha" and s["seed"] == "1" for s in foamd.submitted)
    assert out.getvalue().count("submitted") == 3
    # Each rerun matches its run and diagnosis; run again, nothing more.
    diag = matching._diag_jobs(study, foamd)
    runs = study.runs()
    assert {(runs[i].point["cells.alpha"], name) for i, ds in diag.items() for name in ds} == {
        (0.4375, "keep-out"), (0.4375, "reference-step"), (0.6, "reference-step")}
    assert st.submit_diagnoses(study, foamd) == 0
    # Cancelled by hand: a decision, not submitted again; lost to an engine error: again.
    from activefoam.v1 import job_pb2
    for j in foamd.jobs["diag:alpha"]:
        j.state = job_pb2.JobState.Value("JOB_STATE_CANCELLED" if "keep_out" in j.spec_json
                                         else "JOB_STATE_FAILED")
        j.failure_kind = "" if "keep_out" in j.spec_json else "engine-error"
    assert st.submit_diagnoses(study, foamd) == 2
    assert all(s["numerics.dt_s"] == "0.25" for s in foamd.submitted[3:])
    assert all(s["key"].endswith(":1") for s in foamd.submitted[3:])
    # A study with diagnoses off submits none, for the same failed runs.
    off = tmp_path / "off.toml"
    off.write_text(_without_tables(study.path.read_text()).replace(
        'seeds = [1, 2]\n', 'seeds = [1, 2]\ndiagnose = false\n'))
    fresh = _FakeFoamd({"alpha": 0.4375})
    _diagnosed_jobs(fresh)
    assert st.submit_diagnoses(st.load(off), fresh) == 0 and not fresh.submitted


def test_a_carried_failures_diagnosis_that_did_not_end_in_its_store_is_rerun_here(tmp_path):
    # The earlier store's data: seed 1 failed in the simulation at both α; at α 0.4375 its
    # keep-out rerun was still queued when the data was collected (that store is gone), at α 0.6
    # its reference-step rerun had ended.
    study = _diagnosed_study(tmp_path)
    d = tmp_path / "earlier"
    d.mkdir()
    rows = []
    for seed, a, kind, diagnoses in (
            (1, 0.4375, "interpenetration",
             "keep-out: queued (0 %) (j-gone-1); reference-step: ran to the end (j-gone-2)"),
            (1, 0.6, "volume-drift", "reference-step: failed too: volume-drift at 100 s (j-g3)"),
            (2, 0.4375, "", ""), (2, 0.6, "", "")):
        run = st.Run({"cells.alpha": a}, seed)
        rows.append({"run": len(rows), "cells.alpha": a, "seed": seed,
                     "settings": json.dumps(study.settings(run), sort_keys=True),
                     "job_id": f"j-old-{a}-{seed}", "state": "failed" if kind else "succeeded",
                     "failure_kind": kind, "t_end_s": 100.0 if kind else 240.0,
                     "diagnoses": diagnoses, "diag_ran_past": "ran to" in diagnoses})
    _write_data(d, rows, [], [])
    carried = st.carried_runs(study, d)
    assert len(carried.rows) == 4
    foamd = _FakeFoamd({"alpha": 0.4375})
    out = io.StringIO()
    # Only the keep-out of α 0.4375: the reruns that ended there stand.
    assert st.submit_diagnoses(study, foamd, out=out, carried=carried) == 1
    (got,) = foamd.submitted
    assert (got["cells.alpha"], got["seed"], got["numerics.remesh_keep_out_um"]) == \
        ("0.4375", "1", "0.75")
    assert "diagnosis 'keep-out' submitted" in out.getvalue()
    assert st.submit_diagnoses(study, foamd, carried=carried) == 0
    # Without the carried rows nothing is submitted (the store holds no run of the study).
    assert st.submit_diagnoses(study, _FakeFoamd({"alpha": 0.4375})) == 0
    # The report lists this store's rerun in place of the stale entry, the other as it was.
    (rerun,) = foamd.jobs["diag:alpha"]
    from activefoam.v1 import job_pb2
    rerun.state, rerun.t_s = job_pb2.JobState.Value("JOB_STATE_SUCCEEDED"), 240.0
    runs = pd.read_csv(st.collect(study, foamd, tmp_path / "data", carried) / "runs.csv")
    row = runs[(runs["seed"] == 1) & (runs["cells.alpha"] == 0.4375)].iloc[0]
    assert row["diagnoses"] == ("keep-out: ran to the end (j-0000); "
                                "reference-step: ran to the end (j-gone-2)")
    assert bool(row["diag_ran_past"])
    row = runs[(runs["seed"] == 1) & (runs["cells.alpha"] == 0.6)].iloc[0]
    assert row["diagnoses"] == "reference-step: failed too: volume-drift at 100 s (j-g3)"
    assert not bool(row["diag_ran_past"])


def _without_tables(text: str) -> str:
    return text[:text.index("[[diagnose]]")]


# What foamd echoes for the keys the built-in diagnoses read, where nothing sets them; and a key
# the preset sets where the spec does not (the study's Δt is explicit).
_ENGINE_ECHO = {"numerics.preset": lambda spec: "standard",
                "numerics.max_penetration_um": lambda spec: 1.0,
                "numerics.remesh_keep_out_um": lambda spec: 0.0,
                "numerics.cg_tol": lambda spec: 1e-3 if spec["numerics"]["preset"] == "reference"
                else 1e-2}


@pytest.mark.parametrize("study_keys,spec_keys,kinds_to", [
    # A study at the default preset: an interpenetration with the keep-out at the guard's 1 µm,
    # the volume drift at the reference preset.
    ("", {}, {"interpenetration": ("keep-out", {"numerics.remesh_keep_out_um": "1.0"}),
              "volume-drift": ("reference-step", {"numerics.preset": "reference"})}),
    # A study at the reference preset: the volume drift at the supplement's Δt 0.1 s.
    ('preset = "reference"\n', {},
     {"interpenetration": ("keep-out", {"numerics.remesh_keep_out_um": "1.0"}),
      "volume-drift": ("supplement-step", {"numerics.dt_s": "0.1"})}),
    # The guard at 0.5 µm: the keep-out at 0.5 µm.
    ("", {"numerics.max_penetration_um": 0.5},
     {"interpenetration": ("keep-out", {"numerics.remesh_keep_out_um": "0.5"}),
      "volume-drift": ("reference-step", {"numerics.preset": "reference"})}),
    # Runs that had a keep-out already: the interpenetration too at the finer step.
    ("", {"numerics.remesh_keep_out_um": 1.0},
     {"interpenetration": ("reference-step", {"numerics.preset": "reference"}),
      "volume-drift": ("reference-step", {"numerics.preset": "reference"})}),
], ids=["standard", "reference", "guard-0.5", "had-keep-out"])
def test_a_study_without_diagnose_tables_gets_the_built_in_diagnoses(tmp_path, study_keys,
                                                                      spec_keys, kinds_to):
    study = _diagnosed_study(tmp_path)
    text = _without_tables(study.path.read_text()).replace(
        'seeds = [1, 2]\n', 'seeds = [1, 2]\n' + study_keys).replace(
        '"numerics.dt_s" = 1.0\n', '"numerics.dt_s" = 1.0\n' + "".join(
            f'"{k}" = {v}\n' for k, v in spec_keys.items()))
    study.path.write_text(text)
    study = st.load(study.path)
    assert not study.diagnoses and study.diagnose
    foamd = _FakeFoamd({"alpha": 0.4375}, derived=_ENGINE_ECHO)
    _diagnosed_jobs(foamd, **{k.replace(".", "__"): v for k, v in spec_keys.items()},
                    **({"numerics__preset": "reference"} if "reference" in study_keys else {}))
    assert st.submit_missing(study, foamd) == (0, 4)  # the failed runs are results
    out = io.StringIO()
    assert st.submit_diagnoses(study, foamd, out=out) == 2
    # One rerun per failed run (seed 1 at both α), with the failed run's keys and the
    # diagnosis's on top, under the diagnosis's name.
    runs = study.runs()
    by_alpha = {s["cells.alpha"]: s for s in foamd.submitted}
    for alpha, kind in (("0.4375", "interpenetration"), ("0.6", "volume-drift")):
        name, keys = kinds_to[kind]
        got = by_alpha[alpha]
        assert got["tag"] == "diag:alpha" and got["seed"] == "1"
        assert got["key"].startswith(f"diag:alpha:{name}:"), got["key"]
        for k, v in keys.items():
            assert got[k] == v, (kind, k)
        # The rest are the run's own keys.
        assert got["numerics.dt_s"] == keys.get("numerics.dt_s", "1.0")
        assert "numerics.remesh_keep_out_um" not in got or kind == "interpenetration" \
            or "numerics.remesh_keep_out_um" in spec_keys
    # Each rerun is matched to its run and diagnosis; run again, nothing more.
    diag = matching._diag_jobs(study, foamd)
    assert {(runs[i].point["cells.alpha"], name) for i, ds in diag.items() for name in ds} == {
        (0.4375, kinds_to["interpenetration"][0]), (0.6, kinds_to["volume-drift"][0])}
    assert st.submit_diagnoses(study, foamd) == 0
    # What the report lists without foamd is what each run's resolved spec gives.
    for run in runs:
        assert st.run_diagnoses(study, foamd, run) == study.listed_diagnoses()


def test_the_built_in_diagnoses_are_the_tables_the_figure_studies_had(tmp_path):
    # The reduced figure studies' [[diagnose]] tables, which the built-in diagnoses replaced:
    # the same names, keys, kinds and titles, so that their committed reports regenerate as
    # they were (the "Failed runs" list names each diagnosis).
    tables = textwrap.dedent("""\
        [[diagnose]]
        name = "keep-out"
        title = "no collapse puts a vertex past the guard's 1 µm inside a touching cell"
        spec = { "numerics.remesh_keep_out_um" = 1.0 }
        kinds = ["interpenetration"]

        [[diagnose]]
        name = "reference-step"
        title = "0.25 s / 1e-3 under the law"
        spec = { "numerics.preset" = "reference" }
        kinds = ["volume-drift", "inverted-triangle", "non-finite", "cg-not-converged",
                 "contact-oscillation", "step-error"]
        """)
    root = Path(__file__).resolve().parents[2]
    for name in ("fig8-reduced", "fig9-reduced", "fig10-reduced", "fig11-reduced",
                 "fig14-reduced", "fig9-scaling", "jam-day"):
        path = root / "studies" / f"{name}.toml"
        now = st.load(path)
        assert not now.diagnoses and now.diagnose, name
        (tmp_path / "specs").mkdir(exist_ok=True)
        (tmp_path / "specs" / now.base.name).write_text(now.base_text)
        text = path.read_text()
        then = tmp_path / path.name
        then.write_text(text.replace("\n[[grid]]", "\n" + tables + "\n[[grid]]", 1)
                        .replace('file = "', 'file = "' + str(root / "studies") + "/"))
        old = st.load(then)
        assert old.diagnoses == now.listed_diagnoses(), name
        data = root / "docs" / "science" / name / "data"
        if data.is_dir():
            runs = st.load_data(now, data).runs
            assert st.failed_runs_markdown(now, runs) == st.failed_runs_markdown(old, runs)


def test_the_built_in_diagnoses_read_the_runs_spec_as_foamd_resolves_it(client, tmp_path):
    # Against a real foamd: each run's diagnoses from its resolved spec are the ones a report
    # lists without foamd (the engine's defaults of the preset and the guard's depth), and
    # each finer step is finer: the reference preset's Δt below the standard one's, 0.1 s below
    # the reference preset's.
    (tmp_path / "base.toml").write_text('scene = "fusion"\n')
    for preset, name in (("", "reference-step"), ('preset = "reference"\n', "supplement-step")):
        f = tmp_path / "s.toml"
        f.write_text(textwrap.dedent("""\
            [study]
            name = "builtin"
            base = "base.toml"
            seeds = [1]
            """) + preset + textwrap.dedent("""\
            [spec]
            duration_s = 240
            [[grid]]
            "cells.alpha" = [0.4375, 0.6]
            [[grid]]
            "cells.alpha" = [0.5]
            "numerics.max_penetration_um" = [0.5]
            """))
        study = st.load(f)
        listed = study.listed_diagnoses()
        assert [d.name for d in listed] == ["keep-out", name, "keep-out"]
        assert [d.spec for d in listed if d.name == "keep-out"] == [
            {"numerics.remesh_keep_out_um": 1.0}, {"numerics.remesh_keep_out_um": 0.5}]
        for run in study.runs():
            got = st.run_diagnoses(study, client, run)
            assert all(d in listed for d in got) and [d.name for d in got] == ["keep-out", name]
            resolved = matching._run_spec(study, client, study.settings(run), run.label()).spec
            keep_out, step = got
            assert keep_out.spec == {
                "numerics.remesh_keep_out_um": resolved["numerics.max_penetration_um"]}
            assert resolved["numerics.remesh_keep_out_um"] == 0
            rerun = matching._run_spec(study, client, study.diag_settings(run, step), "rerun")
            assert rerun.spec["numerics.dt_s"] < resolved["numerics.dt_s"]


def test_a_diagnosis_whose_numerics_the_run_already_had_is_not_rerun(tmp_path):
    # The failed run's resolved spec already has the diagnosis's values (here a remeshing
    # interval the engine derives from the cells, which the study file does not show): the
    # rerun would be the same run, failing bit for bit.
    from activefoam.v1 import job_pb2
    study = _diagnosed_study(tmp_path)
    f = study.path
    f.write_text(f.read_text().replace('spec = { "numerics.dt_s" = 0.25 }',
                                       'spec = { "numerics.remesh_every_s" = 300 }'))
    study = st.load(f)
    # The volume drift's run (α 0.6) remeshed every 300 s already; the interpenetration's 150 s.
    foamd = _FakeFoamd({"alpha": 0.4375}, derived={
        "numerics.remesh_every_s": lambda spec: 300 if spec["cells"]["alpha"] == 0.6 else 150})
    _diagnosed_jobs(foamd)
    out = io.StringIO()
    assert st.submit_diagnoses(study, foamd, out=out) == 2  # α 0.4375's two, not α 0.6's
    assert all(s["cells.alpha"] == "0.4375" for s in foamd.submitted)
    assert "cells.alpha=0.6, seed 1 failed (volume-drift): diagnosis 'reference-step' " + \
        st.NOOP_TEXT + " (numerics.remesh_every_s)" in out.getvalue()
    foamd.job = lambda jid: type("J", (), {"results_message": lambda self, _: _NoResults()})()
    for j in foamd.jobs["diag:alpha"]:
        j.reason, j.outcome, j.progress, j.t_s = "", "", 0.0, 0.0
        j.state = job_pb2.JobState.Value("JOB_STATE_QUEUED")
    runs = pd.read_csv(st.collect(study, foamd, tmp_path / "report" / "data") / "runs.csv")
    b = runs[(runs["seed"] == 1) & (runs["cells.alpha"] == 0.6)].iloc[0]
    assert b["diagnoses"] == f"reference-step: {st.NOOP_TEXT}" and not b["diag_ran_past"]


class _NoResults:
    results, columns, samples, curves = [], [], [], []


def test_a_failure_a_diagnosis_ran_past_is_reported_and_left_out_of_the_failed_verdict(tmp_path):
    from activefoam.study import verdicts
    from activefoam.v1 import job_pb2
    study = _diagnosed_study(tmp_path)
    foamd = _FakeFoamd({"alpha": 0.4375})
    _diagnosed_jobs(foamd)
    st.submit_diagnoses(study, foamd)
    # The keep-out rerun of α 0.4375 ran to the end; its reference-step rerun failed too, at
    # 80 s; α 0.6's reference-step rerun is still running.
    for j in foamd.jobs["diag:alpha"]:
        spec = json.loads(j.spec_json)
        j.reason, j.outcome, j.progress = "", "", 0.4
        if spec["numerics"].get("remesh_keep_out_um") == 0.75:
            j.state, j.t_s = job_pb2.JobState.Value("JOB_STATE_SUCCEEDED"), 240.0
        elif spec["cells"]["alpha"] == 0.4375:
            j.state, j.t_s = job_pb2.JobState.Value("JOB_STATE_FAILED"), 80.0
            j.failure_kind = "interpenetration"
        else:
            j.state, j.t_s = job_pb2.JobState.Value("JOB_STATE_RUNNING"), 96.0
    foamd.job = lambda jid: type("J", (), {"results_message": lambda self, _: _NoResults()})()
    out = st.collect(study, foamd, tmp_path / "report" / "data")
    runs = pd.read_csv(out / "runs.csv")
    a, b = (runs[(runs["seed"] == 1) & (runs["cells.alpha"] == x)].iloc[0] for x in (0.4375, 0.6))
    assert a["diag_ran_past"] and not b["diag_ran_past"]
    assert "keep-out: ran to the end" in a["diagnoses"]
    assert "reference-step: failed too: interpenetration at 80 s" in a["diagnoses"]
    assert "reference-step: running (40 %)" in b["diagnoses"]
    assert runs[runs["seed"] == 2]["diagnoses"].isna().all()
    table = st.summary_table(study, runs)
    assert list(table["failed"]) == [1, 1] and list(table["failed_ran_past"]) == [1, 0]
    md = st.summary_markdown(study, table) + st.failed_runs_markdown(study, runs)
    assert "1 (interpenetration; 1 ran past on a diagnosis rerun)" in md
    assert "1 (volume-drift)" in md
    assert "## Failed runs" in md and "keep-out sets numerics.remesh_keep_out_um = 0.75" in md
    # The verdict's `failed`: α 0.4375 keeps only its success (the failure was the remesher's),
    # α 0.6 its failure and its success.
    assert verdicts._values(runs, {"cells.alpha": 0.4375}, "failed") == [0.0]
    assert sorted(verdicts._values(runs, {"cells.alpha": 0.6}, "failed")) == [0.0, 1.0]


def test_retry_failed_takes_every_kind_or_the_named_ones_and_refuses_unknown_kinds():
    assert submission._retry_kinds(None) is False
    assert submission._retry_kinds("preparation-failed, volume-drift") == {"preparation-failed",
                                                                   "volume-drift"}
    for bad in ("prep-failed", "volume-drift,engine-error", ","):
        with pytest.raises(st.StudyError, match="--retry-kinds: .*allowed: .*preparation-failed"):
            submission._retry_kinds(bad)
    prep = [_FakeJob("j-1", 4, {}, state="FAILED", failure_kind="preparation-failed")]
    drift = [_FakeJob("j-2", 4, {}, state="FAILED", failure_kind="volume-drift")]
    lost = [_FakeJob("j-3", 4, {}, state="FAILED", failure_kind="engine-error")]
    assert not submission._needs_job(prep, False) and submission._needs_job(prep, True)
    assert submission._needs_job(prep, {"preparation-failed"})
    assert not submission._needs_job(drift, {"preparation-failed"})
    assert submission._needs_job(lost, {"preparation-failed"}) and submission._needs_job(lost, False)


def _probe_study(tmp: Path, extra: str):
    return _alpha_study_1s(tmp, "diagnose = false\n" + extra)


class _ProbeResults:
    """A run's results with the shape probe's column and the depth probe's curves."""
    results = []
    columns = ["theta_deg", "shape_index_mean", "shape_index_smoothed_mean"]

    def __init__(self, jid):
        k = float(jid.rsplit("-", 1)[1])   # the seed
        S = type("S", (), {})
        self.samples = []
        for t in (0.0, 120.0, 240.0):
            s = S()
            s.t_s, s.values = t, [30.0 + t / 60, 5.0 + k, 4.9 + k + t / 1000]
            self.samples.append(s)
        self.curves = []
        for name in ("msrd", "msrd_surface", "msrd_buried"):
            c = S()
            c.name, c.x, c.y = name, [60.0, 120.0], [k, 2 * k + len(name)]
            self.curves.append(c)


def test_a_studys_columns_and_curves_reach_its_data_folder(tmp_path):
    study = _probe_study(tmp_path, 'columns = ["shape_index_smoothed_mean"]\n'
                                   'curves = ["msrd_surface"]\n')
    foamd = _FakeFoamd({"alpha": 0.4375})
    _diagnosed_jobs(foamd)   # seed 1 failed at both α, seed 2 succeeded
    foamd.job = lambda jid: type("J", (), {"results_message":
                                          lambda self, _: _ProbeResults(jid)})()
    out = st.collect(study, foamd, tmp_path / "data")
    samples = pd.read_csv(out / "samples.csv.gz")
    assert "shape_index_smoothed_mean" in samples and "shape_index_mean" in samples
    one = samples[samples["job_id"] == "j-0.6-2"].sort_values("t_s")
    assert list(one["shape_index_smoothed_mean"]) == pytest.approx([6.9, 7.02, 7.14])
    curves = pd.read_csv(out / "curves.csv.gz")
    assert set(curves["curve"]) == {"msrd_surface"}   # the MSRD keeps its own file
    assert list(curves[curves["job_id"] == "j-0.6-2"]["y"]) == [2.0, 16.0]
    assert len(pd.read_csv(out / "msrd.csv.gz")) == 8   # every run's, two lags each
    data = st.load_data(study, out)
    assert set(data.curves["job_id"]) == {"j-0.4375-1", "j-0.6-1", "j-0.4375-2", "j-0.6-2"}
    # A study that names none writes what it always did.
    (tmp_path / "plain").mkdir()
    plain = st.collect(_probe_study(tmp_path / "plain", ""), foamd, tmp_path / "plain-data")
    assert not (plain / "curves.csv.gz").exists()
    assert "shape_index_smoothed_mean" not in pd.read_csv(plain / "samples.csv.gz")
    assert st.load_data(study, plain).curves is None


def test_a_column_or_curve_the_runs_lack_is_refused_naming_it(tmp_path):
    foamd = _FakeFoamd({"alpha": 0.4375})
    _diagnosed_jobs(foamd)
    foamd.job = lambda jid: type("J", (), {"results_message":
                                          lambda self, _: _ProbeResults(jid)})()
    study = _probe_study(tmp_path, 'columns = ["elongation_mean"]\n')
    with pytest.raises(st.StudyError, match=r"study.columns: .* no sample column "
                                            r"elongation_mean: .*\[observe\]"):
        st.collect(study, foamd, tmp_path / "data")
    study = _probe_study(tmp_path, 'curves = ["msrd_layer0"]\n')
    with pytest.raises(st.StudyError, match=r"study.curves: .*seed 2 .* no curve msrd_layer0"):
        st.collect(study, foamd, tmp_path / "data2")
    # A run that failed before its first step has no columns to lack.
    study = _probe_study(tmp_path, 'columns = ["shape_index_smoothed_mean"]\n')
    foamd.job = lambda jid: type("J", (), {"results_message": lambda self, _: (
        _NoResults() if jid.endswith("-1") else _ProbeResults(jid))})()
    samples = pd.read_csv(st.collect(study, foamd, tmp_path / "data3") / "samples.csv.gz")
    assert set(samples["job_id"]) == {"j-0.4375-2", "j-0.6-2"}
    for bad, msg in (('columns = "x"', "a list of up to 100 column names"),
                     ('columns = ["Theta"]', "a list of up to 100 column names"),
                     ('columns = ["theta_deg"]', "theta_deg given twice"),
                     ('curves = ["a", "a"]', "a given twice"),
                     ('curves = ["msrd"]', "msrd given twice")):
        with pytest.raises(st.StudyError, match=f"study.{bad.split()[0]}: {msg}"):
            _probe_study(tmp_path, bad + "\n")
