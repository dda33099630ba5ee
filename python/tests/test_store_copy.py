"""A foamd store carried to another machine (activefoam.study.store_copy, `study save-store` /
`restore-store`): a job running when the copy was taken resumes there from its checkpoint."""

import json
import time

import pytest

from activefoam import Client
from activefoam.study import store_copy as sc
from activefoam.client import state_name
from conftest import TINY_FUSION, Foamd

SPEC = 'seed = 3\nduration_s = 3600\n' + TINY_FUSION


def _wait(client, jid, pred, timeout=240, cap=1800):
    # A job that moves is waited for (the suite may share its cores with other work: a total
    # deadline failed it under load); one that stops moving for `timeout` s is a failure.
    start = last_move = time.monotonic()
    seen = None
    while True:
        info = client.job(jid).info()
        if pred(info):
            return info
        now = time.monotonic()
        if (info.state, info.progress) != seen:
            seen, last_move = (info.state, info.progress), now
        assert now - last_move < timeout and now - start < cap, \
            f"job {jid}: {state_name(info.state)} at {info.progress:.1%}, unchanged for " \
            f"{now - last_move:.0f} s ({now - start:.0f} s in all)"
        time.sleep(0.2)


def test_a_running_job_resumes_from_its_checkpoint_in_a_restored_store(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a = Foamd(tmp_path / "a",
              extra_args=["--checkpoint-every-s", "30"])
    try:
        with Client(a.address) as c:
            (tmp_path / "spec.toml").write_text(SPEC)
            jid = c.submit(tmp_path / "spec.toml").id
            _wait(c, jid, lambda j: state_name(j.state) == "running" and j.progress >= 0.1)
            # foamd keeps the store to itself while it runs: a copy is refused, naming why.
            with pytest.raises(sc.StoreCopyError, match="in use .*stop foamd first"):
                sc.save(tmp_path / "a" / "foamd.db", tmp_path / "copy", engine="engine-X")
    finally:
        a.stop()  # SIGTERM: the running job is checkpointed where it is and re-queued
    m = sc.save(tmp_path / "a" / "foamd.db", tmp_path / "copy", engine="engine-X")
    assert m["jobs"] == 1 and m["checkpoints"] == 1 and m["by_state"] == {"queued": 1}, m
    assert m["spheroids"] >= 1 and m["engine"] == "engine-X"
    assert json.loads((tmp_path / "copy" / sc.MANIFEST).read_text()) == m

    b_db = tmp_path / "b" / "foamd.db"
    # Another engine: refused, and nothing is written.
    with pytest.raises(sc.StoreCopyError, match="saved under engine engine-X"):
        sc.restore(tmp_path / "copy", b_db, engine="engine-Y")
    assert not b_db.exists()
    sc.restore(tmp_path / "copy", b_db, engine="engine-X")
    with pytest.raises(sc.StoreCopyError, match="exists; a restore overwrites nothing"):
        sc.restore(tmp_path / "copy", b_db, engine="engine-X")
    assert any((tmp_path / "b" / "spheroids").iterdir())

    b = Foamd(tmp_path / "b")
    try:
        with Client(b.address) as c:
            j = _wait(c, jid, lambda j: state_name(j.state) in ("succeeded", "failed",
                                                                  "cancelled"), timeout=300)
            assert state_name(j.state) == "succeeded", j.reason
            samples = c.job(jid).samples()
            assert len(samples) == 3600 // 30 + 1
            assert list(samples["t_s"]) == [30.0 * k for k in range(121)]
    finally:
        b.stop()
    assert "re-queued at shutdown" in (tmp_path / "a" / "foamd.log").read_text()
    log = (tmp_path / "b" / "foamd.log").read_text()
    resumed = [ln for ln in log.splitlines() if "resuming from checkpoint at t = " in ln]
    assert resumed and float(resumed[0].split("t = ")[1].split()[0]) >= 360, resumed
    # The spheroids came with the copy: the job did not prepare them again.
    assert "relaxing" not in log


def test_a_copy_without_snapshots_leaves_out_only_the_snapshots(tmp_path):
    import sqlite3
    db = tmp_path / "s.db"
    con = sqlite3.connect(str(db))
    con.executescript("""
        CREATE TABLE jobs(id TEXT, state INTEGER);
        CREATE TABLE checkpoints(job_id TEXT, data BLOB);
        CREATE TABLE samples(job_id TEXT, t_s REAL);
        CREATE TABLE snapshots(job_id TEXT, data BLOB);
        INSERT INTO jobs VALUES ('j-1', 3), ('j-2', 1);
        INSERT INTO checkpoints VALUES ('j-2', x'00');
        INSERT INTO samples VALUES ('j-1', 0), ('j-1', 30);
        INSERT INTO snapshots VALUES ('j-1', zeroblob(100000)), ('j-2', zeroblob(100000));
    """)
    con.commit()
    con.close()
    m = sc.save(db, tmp_path / "copy", engine="e", snapshots=False)
    assert m["snapshots_left_out"] == 2 and m["jobs"] == 2 and m["checkpoints"] == 1
    sc.restore(tmp_path / "copy", tmp_path / "r.db", engine="e")
    con = sqlite3.connect(str(tmp_path / "r.db"))
    assert con.execute("SELECT count(*) FROM snapshots").fetchone()[0] == 0
    assert con.execute("SELECT count(*) FROM samples").fetchone()[0] == 2
    assert con.execute("SELECT count(*) FROM checkpoints").fetchone()[0] == 1
    con.close()
    assert (tmp_path / "r.db").stat().st_size < 100000  # vacuumed
    full = sc.save(db, tmp_path / "full", engine="e", engine_commit="c0ffee")
    assert full["snapshots_left_out"] == 0 and full["engine_commit"] == "c0ffee"


def test_a_missing_copy_or_store_is_a_clear_error(tmp_path):
    with pytest.raises(sc.StoreCopyError, match="no store at"):
        sc.save(tmp_path / "none.db", tmp_path / "copy")
    with pytest.raises(sc.StoreCopyError, match="holds no saved store"):
        sc.restore(tmp_path, tmp_path / "x.db")
