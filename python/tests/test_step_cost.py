"""bench/step_cost.py: the cost table from hand-built foam-run folders (no simulation runs)."""
import importlib.util
import json
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[2] / "bench" / "step_cost.py"
_spec = importlib.util.spec_from_file_location("step_cost", _PATH)
sc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(sc)


def run_folder(path, *, setup_s=2.5, wall_s=12.5, steps=100, t_s=50.0, ok=True,
               failure="none", samples=True):
    """A foam-run folder: `steps` steps of Δt 0.5 s after `setup_s` of loading and setup."""
    path.mkdir()
    (path / "spec.json").write_text(json.dumps({"numerics": {
        "integrator": "contact-implicit-consistent", "dt_s": 0.5,
        "preconditioner": "block-jacobi", "cg_tol": 0.01}}))
    (path / "summary.json").write_text(json.dumps({
        "ok": ok, "failure": failure, "steps": steps, "t_s": t_s, "wall_s": wall_s,
        "cg_iters_mean": 25.84, "phase_wall_s": {
            "geometry": 0.05, "contacts": 2.0, "forces": 0.1, "matrix": 0.6, "solve": 5.0,
            "remesh": 0.8}}))
    if samples:
        (path / "samples.csv").write_text(
            f"t_s,steps,wall_s,cg_iters_mean\n0,0,{setup_s},0\n{t_s},{steps},{wall_s},25.84\n")
    return path


def cells(line):
    return [c.strip() for c in line.strip().strip("|").split("|")]


def test_the_setup_before_the_first_sample_is_not_timed_and_phases_are_per_step(tmp_path):
    r = sc.read_run(run_folder(tmp_path / "a"))
    assert r["timed_s"] == pytest.approx(10.0)  # 12.5 s of the run less 2.5 s of setup
    c = cells(sc.row(r))
    assert c[:8] == ["a", "contact-implicit-consistent", "0.5", "block-jacobi", "0.01", "100",
                     "25.8", "100"]                      # 10 s / 100 steps = 100 ms
    assert c[8:14] == ["0.5", "20.0", "1.0", "6.0", "50.0", "8.0"]  # phases, ms a step
    # 10 s of wall for 50 simulated seconds: 0.2 min a simulated minute, 4.8 h a day.
    assert c[14:] == ["0.2 min", "5 h"]


def test_a_slower_setup_changes_nothing_but_the_untimed_part(tmp_path):
    a = sc.read_run(run_folder(tmp_path / "a"))
    b = sc.read_run(run_folder(tmp_path / "b", setup_s=200.0, wall_s=210.0))  # a preparation
    assert cells(sc.row(a))[1:] == cells(sc.row(b))[1:]


def test_a_failed_run_says_so_and_a_run_without_steps_has_no_rates(tmp_path):
    f = sc.row(sc.read_run(run_folder(tmp_path / "f", ok=False, failure="inverted-triangle")))
    assert f.endswith("| failed: inverted-triangle")
    z = cells(sc.row(sc.read_run(run_folder(tmp_path / "z", steps=0, t_s=0.0, wall_s=2.5))))
    assert z[7:] == ["—"] * 9


def test_table_has_one_header_and_a_row_a_run_in_the_given_order(tmp_path, capsys):
    a, b = run_folder(tmp_path / "n100-t2"), run_folder(tmp_path / "n100-t16")
    assert sc.main(["table", str(a), str(b)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4
    assert len(cells(lines[1])) == len(cells(lines[0])) == len(cells(lines[2]))
    assert [cells(x)[0] for x in lines[2:]] == ["n100-t2", "n100-t16"]


def test_what_is_not_a_finished_run_is_named(tmp_path):
    with pytest.raises(sc.RunError, match="no summary.json"):
        sc.read_run(tmp_path)
    with pytest.raises(sc.RunError, match="no samples.csv"):
        sc.read_run(run_folder(tmp_path / "s", samples=False))
    bad = run_folder(tmp_path / "t")
    (bad / "samples.csv").write_text("t_s,steps,wall_s\n15,30,3.0\n")
    with pytest.raises(sc.RunError, match="no sample at t = 0"):
        sc.read_run(bad)
    with pytest.raises(SystemExit, match="no summary.json"):
        sc.main(["table", str(tmp_path)])


def test_the_command_samples_at_the_ends_and_a_configuration_may_set_its_duration():
    def sets(cmd):
        return [cmd[k + 1] for k, w in enumerate(cmd) if w == "--set"]

    name, words = sc.parse_config("consistent 1 s|--set numerics.dt_s=1 --set duration_s=200")
    assert name == "consistent_1_s"
    cmd = sc.foam_run_command("foam-run", "s.toml", "OUT/x", "C", 2, 20.0, words)
    assert cmd[:4] == ["foam-run", "s.toml", "--out", "OUT/x"]
    assert cmd[cmd.index("--spheroid-cache") + 1] == "C"
    assert cmd[cmd.index("--threads") + 1] == "2"
    s = sets(cmd)
    assert "sample_every_s=200" in s and "snapshot_every_s=0" in s
    assert s[-1] == "duration_s=200"  # the configuration's own, last: it wins
    name, words = sc.parse_config("--set numerics.integrator=ros2 --set numerics.dt_s=0.5")
    assert name == "ros2_0.5"
    cmd = sc.foam_run_command("foam-run", "s.toml", "OUT/x", "", 1, 20.0, words)
    assert "--spheroid-cache" not in cmd
    assert {"duration_s=20", "sample_every_s=20"} <= set(sets(cmd))
