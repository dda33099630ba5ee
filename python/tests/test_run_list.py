"""docs/science/tools/run_list.sh: which lines of a page's run list it runs, and how it calls
foam-run (a stand-in that records its arguments)."""
import os
import subprocess
from pathlib import Path

TOOL = Path(__file__).resolve().parents[2] / "docs/science/tools/run_list.sh"


def _run(tmp_path, *groups):
    fake = tmp_path / "foam-run"
    fake.write_text('#!/bin/sh\necho "$@" >> "$(dirname "$0")/calls"\n')
    fake.chmod(0o755)
    (tmp_path / "page").mkdir(exist_ok=True)
    lst = tmp_path / "page" / "runs.txt"
    lst.write_text("# a comment\n\n"
                   "a L2 1 s.toml\n"
                   "b L0.25 2 s.toml cells.l_eta_reduced=0.25 prepare.cells.tau_p_s=600\n"
                   "  # indented comment\n"
                   "a L0.25 1 s.toml cells.l_eta_reduced=0.25\n")
    r = subprocess.run([str(TOOL), str(lst), str(tmp_path / "out"), *groups],
                       env=dict(os.environ, FOAM_RUN=str(fake)), capture_output=True, text=True)
    calls = (tmp_path / "calls").read_text().splitlines() if (tmp_path / "calls").exists() else []
    return r, calls


def test_every_line_runs_in_order_into_name_seed_folders(tmp_path):
    r, calls = _run(tmp_path)
    assert r.returncode == 0, r.stderr
    page, out = tmp_path / "page", tmp_path / "out"
    assert calls == [
        f"{page}/s.toml --out {out}/L2-seed1 --resume --quiet --set seed=1",
        f"{page}/s.toml --out {out}/L0.25-seed2 --resume --quiet --set seed=2 "
        "--set cells.l_eta_reduced=0.25 --set prepare.cells.tau_p_s=600",
        f"{page}/s.toml --out {out}/L0.25-seed1 --resume --quiet --set seed=1 "
        "--set cells.l_eta_reduced=0.25"]


def test_only_the_named_groups_run_and_an_unknown_group_is_an_error(tmp_path):
    r, calls = _run(tmp_path, "a")
    assert r.returncode == 0 and [c.split()[2] for c in calls] == [
        f"{tmp_path}/out/L2-seed1", f"{tmp_path}/out/L0.25-seed1"]
    (tmp_path / "x").mkdir()
    r, _ = _run(tmp_path / "x", "nosuch")
    assert r.returncode == 2 and "no line of" in r.stderr and "nosuch" in r.stderr


def test_a_failed_run_does_not_stop_the_list_and_the_exit_status_names_it(tmp_path):
    # The stand-in fails the run of L0.25-seed2 (as foam-run does when the simulation fails).
    fake = tmp_path / "foam-run"
    fake.write_text('#!/bin/sh\necho "$@" >> "$(dirname "$0")/calls"\n'
                    'case "$*" in *L0.25-seed2*) exit 1 ;; esac\n')
    fake.chmod(0o755)
    (tmp_path / "page").mkdir()
    lst = tmp_path / "page" / "runs.txt"
    lst.write_text("a L2 1 s.toml\na L0.25 2 s.toml\na L0.25 1 s.toml\n")
    r = subprocess.run([str(TOOL), str(lst), str(tmp_path / "out")],
                       env=dict(os.environ, FOAM_RUN=str(fake)), capture_output=True, text=True)
    calls = (tmp_path / "calls").read_text().splitlines()
    assert [c.split()[2] for c in calls] == [
        f"{tmp_path}/out/L2-seed1", f"{tmp_path}/out/L0.25-seed2", f"{tmp_path}/out/L0.25-seed1"]
    assert r.returncode == 1
    assert f"failed: {tmp_path}/out/L0.25-seed2" in r.stderr
