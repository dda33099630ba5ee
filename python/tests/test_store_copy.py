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


# ---- restore-store all or nothing ------------------------------------------------------------

def _saved(tmp_path, spheroids=("sph-a.bin", "sph-b.bin")):
    """A small store (300 jobs, one checkpoint) and its prepared spheroids, saved."""
    import sqlite3
    d = tmp_path / "a"
    (d / "spheroids").mkdir(parents=True)
    con = sqlite3.connect(str(d / "foamd.db"))
    con.executescript("CREATE TABLE jobs(id TEXT PRIMARY KEY, state INTEGER, spec TEXT);"
                      "CREATE TABLE checkpoints(job_id TEXT, data BLOB);"
                      "INSERT INTO checkpoints VALUES ('j-0000', x'00');")
    con.executemany("INSERT INTO jobs VALUES (?, 3, ?)",
                    [(f"j-{i:04d}", "x" * 200) for i in range(300)])
    con.commit()
    con.close()
    for n in spheroids:
        (d / "spheroids" / n).write_bytes(n.encode() * 100)
    sc.save(d / "foamd.db", tmp_path / "copy", engine="e")
    return tmp_path / "copy"


def _nothing_left(root):
    assert not root.exists() or not any(root.rglob("*")), sorted(root.rglob("*"))


def _xz(data):
    import lzma
    return lzma.compress(data)


def _refused(copy, dest, words, **kw):
    with pytest.raises(sc.StoreCopyError) as e:
        sc.restore(copy, dest / "foamd.db", engine="e", **kw)
    for w in words:
        assert w in str(e.value), str(e.value)
    _nothing_left(dest)


def test_a_restore_puts_both_archives_in_place(tmp_path):
    copy = _saved(tmp_path)
    m = sc.restore(copy, tmp_path / "b" / "foamd.db", engine="e")
    assert m["jobs"] == 300 and m["spheroids"] == 2
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == ["foamd.db", "spheroids"]
    assert (tmp_path / "b" / "spheroids" / "sph-a.bin").read_bytes() == b"sph-a.bin" * 100


def test_a_damaged_store_archive_leaves_nothing_behind(tmp_path):
    import lzma
    copy = _saved(tmp_path)
    db_xz = copy / sc.DB_FILE
    good = db_xz.read_bytes()
    raw = lzma.decompress(good)
    dest = tmp_path / "b"
    for damage, words in (
            (good[:len(good) // 2], ["is damaged (EOFError"]),            # cut short
            (b"not xz at all" * 100, ["is damaged (LZMAError"]),         # not xz
            (_xz(b"plain text, no SQLite" * 500), ["holds no foamd store"]),
            (_xz(raw[:4096 * 2] + b"\xab" * 300 + raw[4096 * 2 + 300:]),  # a page overwritten
             ["holds a damaged store (integrity_check: "]),
            (_xz(raw[:len(raw) // 2]), ["holds"])):                       # a store cut short
        db_xz.write_bytes(damage)
        _refused(copy, dest, [f"restore-store: {db_xz}", "nothing was restored"])
    # An existing cache folder keeps what it held.
    db_xz.write_bytes(good[:100])
    (dest / "spheroids").mkdir(parents=True)
    (dest / "spheroids" / "mine.bin").write_bytes(b"mine")
    with pytest.raises(sc.StoreCopyError):
        sc.restore(copy, dest / "foamd.db", engine="e")
    assert sorted(p.name for p in dest.rglob("*")) == ["mine.bin", "spheroids"]


def test_a_damaged_spheroid_archive_leaves_no_store_in_place(tmp_path):
    import io
    import tarfile
    copy = _saved(tmp_path)
    tar_xz = copy / sc.CACHE_FILE
    good = tar_xz.read_bytes()
    dest = tmp_path / "b"
    # Cut short: the store was put in place before the spheroids failed, and a retry said
    # "exists".
    tar_xz.write_bytes(good[:len(good) - 40])
    _refused(copy, dest, [f"restore-store: {tar_xz} is damaged"])

    def archive(*members):
        buf = io.BytesIO()
        with tarfile.open(fileobj=buf, mode="w:xz") as t:
            for info, data in members:
                t.addfile(info, io.BytesIO(data) if data is not None else None)
        return buf.getvalue()

    def member(name, data=b"x", kind=tarfile.REGTYPE, link=""):
        info = tarfile.TarInfo(name)
        info.type, info.linkname, info.size = kind, link, len(data) if kind == tarfile.REGTYPE \
            else 0
        return info, data if kind == tarfile.REGTYPE else None

    for members, name in (([member("../evil")], "'../evil'"),
                          ([member("sph-a.bin"), member("/etc/x")], "'/etc/x'"),
                          ([member("link", kind=tarfile.SYMTYPE, link="/etc/passwd")], "'link'"),
                          ([member("dev", kind=tarfile.CHRTYPE)], "'dev'"),
                          ([member("sub/sph")], "'sub/sph'"),
                          ([member(".hidden")], "'.hidden'"),
                          ([member("twice"), member("twice")], "'twice'")):
        tar_xz.write_bytes(archive(*members))
        _refused(copy, dest, [f"{tar_xz} holds {name}, not a prepared spheroid"])
    # Whole, but not the copy the manifest describes.
    tar_xz.write_bytes(archive(member("sph-a.bin")))
    _refused(copy, dest, [f"{tar_xz} holds 1 files, {copy / sc.MANIFEST} says 2"])
    tar_xz.write_bytes(good)
    sc.restore(copy, dest / "foamd.db", engine="e")


def test_an_archive_is_unpacked_to_its_bound_only(tmp_path):
    # An xz bomb: 64 MiB of zeros in a 10 KB archive against a 1 MiB bound.
    copy = _saved(tmp_path)
    dest = tmp_path / "b"
    (copy / sc.DB_FILE).write_bytes(_xz(bytes(64 << 20)))
    assert (copy / sc.DB_FILE).stat().st_size < 20000
    _refused(copy, dest, [f"{copy / sc.DB_FILE} unpacks to more than the 1 MiB a restore "
                          "may unpack (--max-unpacked-gib)"], max_unpacked=1 << 20)
    # The two archives share the bound: the store fits, the spheroids do not.
    copy = _saved(tmp_path / "2", spheroids=("big.bin",))
    (tmp_path / "2" / "a" / "spheroids" / "big.bin").write_bytes(bytes(4 << 20))
    sc.save(tmp_path / "2" / "a" / "foamd.db", copy, engine="e")
    db_bytes = sc._manifest(copy / sc.MANIFEST)["db_bytes"]
    _refused(copy, dest, [f"{copy / sc.CACHE_FILE} unpacks to more than"],
             max_unpacked=db_bytes + (1 << 20))


def test_a_manifest_that_is_not_one_is_named(tmp_path):
    copy = _saved(tmp_path)
    dest = tmp_path / "b"
    (copy / sc.MANIFEST).write_text("{not json")
    _refused(copy, dest, [f"restore-store: {copy / sc.MANIFEST}: "])
    (copy / sc.MANIFEST).write_text("[1, 2]")
    _refused(copy, dest, [f"{copy / sc.MANIFEST}: not a manifest"])
    (copy / sc.MANIFEST).write_text(json.dumps({"engine": "e", "jobs": 299}))
    _refused(copy, dest, [f"{copy / sc.DB_FILE} holds 300 jobs, {copy / sc.MANIFEST} says 299"])


def test_restore_store_errors_are_one_line_and_exit_2(tmp_path):
    import subprocess
    import sys
    copy = _saved(tmp_path)
    (copy / sc.DB_FILE).write_bytes(b"garbage" * 10)
    dest = tmp_path / "b"
    r = subprocess.run([sys.executable, "-m", "activefoam.study", "restore-store", str(copy),
                        "--db", str(dest / "foamd.db"), "--engine", "e"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith(f"error: restore-store: {copy / sc.DB_FILE} is damaged")
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    _nothing_left(dest)
    r = subprocess.run([sys.executable, "-m", "activefoam.study", "restore-store", str(copy),
                        "--db", str(dest / "foamd.db"), "--max-unpacked-gib", "nan"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "--max-unpacked-gib: nan" in r.stderr, r.stderr
