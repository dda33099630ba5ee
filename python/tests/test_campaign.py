"""scripts/campaign.sh: a study campaign carried across machines that do not outlive the work
(start, stop with the store saved, start again on a new machine, report)."""

import os
import subprocess
import textwrap
import time
from pathlib import Path

import pandas as pd
import pytest

from activefoam import Client
from activefoam.client import state_name
from conftest import TINY_FUSION, _free_port

ROOT = Path(__file__).resolve().parents[2]

def test_a_campaign_resumes_on_a_new_machine_and_takes_committed_runs_as_done(tmp_path):
    foamd = os.environ.get("FOAMD_EXE")
    if not foamd or not Path(foamd).exists():
        pytest.skip("FOAMD_EXE does not name a built foamd (ctest sets it)")
    build = Path(foamd).resolve().parents[1]
    studies = tmp_path / "studies"
    studies.mkdir()
    (studies / "base.toml").write_text(TINY_FUSION)
    (studies / "tiny.toml").write_text(textwrap.dedent("""\
        [study]
        name = "tiny"
        base = "base.toml"
        seeds = [1]
        x = "cells.alpha"
        [spec]
        duration_s = 1800
        [[grid]]
        "cells.alpha" = [0.4375, 0.6]
        """))
    (studies / "campaign.txt").write_text("# the test's campaign\ntiny.toml\n")
    port = _free_port()
    env = dict(os.environ, FOAM_BUILD_DIR=str(build), FOAM_SERVER=f"127.0.0.1:{port}",
               CAMPAIGN_DB=str(tmp_path / "machine" / "c.db"),
               CAMPAIGN_FILE=str(studies / "campaign.txt"),
               CAMPAIGN_SAVED=str(tmp_path / "saved"), CAMPAIGN_SCIENCE=str(tmp_path / "science"),
               CAMPAIGN_WORKERS="1")

    def campaign(*args, ok=True):
        r = subprocess.run([str(ROOT / "scripts/campaign.sh"), *args], env=env, text=True,
                           capture_output=True, timeout=300)
        assert (r.returncode == 0) == ok, r.stderr
        return r

    try:
        assert "2 runs submitted" in campaign("start").stderr
        with Client(env["FOAM_SERVER"]) as c:
            deadline = time.monotonic() + 120
            while not any(j.progress >= 0.2 for j in c.job_infos(tag="study:tiny")):
                assert time.monotonic() < deadline
                time.sleep(0.2)
        campaign("stop")  # one run cut off mid-way, checkpointed, the store saved
    finally:
        subprocess.run([str(ROOT / "scripts/campaign.sh"), "stop"], env=env, capture_output=True)
    assert (tmp_path / "saved" / "MANIFEST.json").is_file()

    # A new machine: no store. start restores it, the cut-off run resumes from its checkpoint.
    import shutil
    shutil.rmtree(tmp_path / "machine")
    try:
        r = campaign("start")
        assert "restore-store: 2 jobs" in r.stderr and "0 runs submitted, 2 already" in r.stderr
        with Client(env["FOAM_SERVER"]) as c:
            deadline = time.monotonic() + 240
            while not all(state_name(j.state) == "succeeded" for j in c.job_infos(tag="study:tiny")):
                assert time.monotonic() < deadline
                time.sleep(0.5)
        assert "tiny reported" in campaign("report").stderr
        campaign("stop")
    finally:
        subprocess.run([str(ROOT / "scripts/campaign.sh"), "stop"], env=env, capture_output=True)
    log = (tmp_path / "machine" / "c-foamd.log").read_text()
    assert "resuming from checkpoint" in log
    runs = pd.read_csv(tmp_path / "science" / "tiny" / "data" / "runs.csv")
    assert list(runs["state"]) == ["succeeded", "succeeded"]

    # Both the machine and the saved store lost: the committed data holds the runs, nothing is
    # submitted again.
    shutil.rmtree(tmp_path / "machine")
    shutil.rmtree(tmp_path / "saved")
    try:
        r = campaign("start")
        assert "2 ended runs in" in r.stderr and "0 runs submitted, 2 already" in r.stderr
        # The study moves to another CG tolerance, then to a third: the second's jobs, queued or
        # running, are no runs of the file any more; start names them, --cancel-stale cancels
        # them (and leaves the third's alone).
        tiny = studies / "tiny.toml"
        plain = tiny.read_text()
        tiny.write_text(plain.replace("duration_s = 1800",
                                      'duration_s = 1800\n"numerics.cg_tol" = 0.01'))
        assert "2 runs submitted" in campaign("start").stderr
        with Client(env["FOAM_SERVER"]) as c:
            second = {j.id for j in c.job_infos(tag="study:tiny")}
        tiny.write_text(plain.replace("duration_s = 1800",
                                      'duration_s = 1800\n"numerics.cg_tol" = 0.002'))
        r = campaign("start")
        assert "2 queued or running jobs of tag study:tiny are no run" in r.stderr, r.stderr
        assert "2 runs submitted" in r.stderr
        r = campaign("start", "--cancel-stale")
        assert "cancelled 2 jobs" in r.stderr and "0 runs submitted, 2 already" in r.stderr
        with Client(env["FOAM_SERVER"]) as c:
            states = {j.id: state_name(j.state) for j in c.job_infos(tag="study:tiny")}
        # A running job stops at its next step; the third's are untouched.
        assert all(states[j] in ("cancelled", "running") for j in second), states
        assert all(s in ("queued", "running") for j, s in states.items() if j not in second)
    finally:
        subprocess.run([str(ROOT / "scripts/campaign.sh"), "stop"], env=env, capture_output=True)

    # The store's engine is not this checkout's (and of no commit here): start refuses, naming
    # --engine-changed; with it the checkout's engine takes over and is recorded for next time.
    engine_file = tmp_path / "machine" / "c-engine.txt"
    here = engine_file.read_text().split()
    engine_file.write_text("0" * 40 + " -\n")
    try:
        r = campaign("start", ok=False)
        assert "--engine-changed" in r.stderr, r.stderr
        r = campaign("start", "--engine-changed")
        assert "takes over (--engine-changed)" in r.stderr, r.stderr
        assert engine_file.read_text().split() == here
    finally:
        subprocess.run([str(ROOT / "scripts/campaign.sh"), "stop"], env=env, capture_output=True)
