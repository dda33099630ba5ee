"""A copy of a foamd store that a study can continue from on another machine.

A study's runs live in foamd's SQLite store: jobs, samples, results, and each running job's last
checkpoint. Where the machine does not outlive the work (a cloud node, a sandbox, a
cluster allocation), `save` writes a copy of the store and of its prepared spheroids to a folder;
`restore` puts them back under a new database path. foamd started there resumes the jobs that
were running from their checkpoints; finished runs are not run again.

foamd keeps its store to itself while it runs (one process: server/heap_shm_vfs.h), so `save`
needs it stopped. Stopping it loses nothing: on SIGTERM it checkpoints its running jobs where
they are and re-queues them, and it resumes them when it starts again.

A checkpoint resumes bit for bit only under the engine that wrote it: foamd checks the spec's
fingerprint, not the engine. The copy therefore records the engine it ran (the git tree of
engine/, or what the caller names), and `restore` refuses a copy made under another engine
unless told that the step's results did not change (`engine_changed_ok`).

    kill -TERM <foamd>; python3 -m activefoam.study save-store DIR --db STORE.db [--engine ID]
    python3 -m activefoam.study restore-store DIR --db STORE.db [--engine-changed]
"""

from __future__ import annotations

import json
import lzma
import os
import shutil
import sqlite3
import subprocess
import tarfile
import tempfile
import time
from pathlib import Path
from typing import Any, Dict, Optional

DB_FILE = "store.db.xz"
CACHE_FILE = "spheroids.tar.xz"
MANIFEST = "MANIFEST.json"


class StoreCopyError(ValueError):
    """A copy that cannot be made or restored: says why and what to do."""


def engine_id(repo: Optional[os.PathLike] = None) -> str:
    """The git tree of engine/ in the checkout holding this file (or `repo`), with '+dirty' when
    engine/ has uncommitted changes; 'unknown' outside a git checkout."""
    root = Path(repo) if repo else Path(__file__).resolve().parents[2]
    try:
        tree = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD:engine"],
                              capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--", "engine"],
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return tree + ("+dirty" if dirty else "")


def _cache_dir(db: Path, cache: Optional[os.PathLike]) -> Path:
    # foamd's default: 'spheroids' next to the database (server/main.cc).
    return Path(cache) if cache else db.parent / "spheroids"


def _counts(db: Path) -> Dict[str, Any]:
    con = sqlite3.connect(str(db))
    try:
        jobs = dict(con.execute("SELECT state, count(*) FROM jobs GROUP BY state").fetchall())
        ckpt = con.execute("SELECT count(*) FROM checkpoints").fetchone()[0]
        total = con.execute("SELECT count(*) FROM jobs").fetchone()[0]
    finally:
        con.close()
    from activefoam.client import state_name
    return {"jobs": total, "checkpoints": ckpt,
            "by_state": {state_name(int(s)): n for s, n in sorted(jobs.items())}}


def _replace(src: Path, dst: Path) -> None:
    os.replace(src, dst)  # same folder: atomic; a reader sees the old file or the new


def save(db: os.PathLike, out_dir: os.PathLike, engine: Optional[str] = None,
         cache: Optional[os.PathLike] = None, snapshots: bool = True,
         engine_commit: str = "") -> Dict[str, Any]:
    """Writes DIR/store.db.xz (a copy of the store, which foamd must not be using),
    DIR/spheroids.tar.xz (the prepared spheroids, if any) and DIR/MANIFEST.json; returns the
    manifest. Each file replaces the previous one atomically, the manifest last. Without
    `snapshots` the copy leaves out the jobs' snapshots (the 3D frames: ~1 MB a 6 h 2 × 20 run,
    which no report reads); the manifest counts what was left out. `engine_commit`: a commit
    whose engine/ is `engine`, from which the next machine can build the same foamd."""
    db = Path(db)
    if not db.is_file():
        raise StoreCopyError(f"save-store: no store at {db} (--db names foamd's database)")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out) as tmp:
        copy = Path(tmp) / "store.db"
        src = sqlite3.connect(str(db), timeout=2)
        dst = sqlite3.connect(str(copy))
        try:
            src.backup(dst)
        except sqlite3.OperationalError as e:
            raise StoreCopyError(
                f"save-store: {db} is in use ({e}): stop foamd first (SIGTERM checkpoints its "
                "running jobs and re-queues them; nothing is lost), save, then start it "
                "again") from None
        finally:
            dst.close()
            src.close()
        dropped = 0
        if not snapshots:
            con = sqlite3.connect(str(copy))
            try:
                dropped = con.execute("SELECT count(*) FROM snapshots").fetchone()[0]
                con.execute("DELETE FROM snapshots")
                con.commit()
                con.execute("VACUUM")
            finally:
                con.close()
        counts = _counts(copy)
        with copy.open("rb") as f, lzma.open(Path(tmp) / DB_FILE, "wb", preset=6) as z:
            shutil.copyfileobj(f, z)
        cache_dir = _cache_dir(db, cache)
        spheroids = sorted(p for p in cache_dir.glob("*") if p.is_file()) \
            if cache_dir.is_dir() else []
        if spheroids:
            with tarfile.open(Path(tmp) / CACHE_FILE, "w:xz") as t:
                for p in spheroids:
                    t.add(p, arcname=p.name)
        manifest = {"saved_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                    "engine": engine or engine_id(), "engine_commit": engine_commit,
                    "db_bytes": copy.stat().st_size,
                    "spheroids": len(spheroids), "snapshots_left_out": dropped, **counts}
        _replace(Path(tmp) / DB_FILE, out / DB_FILE)
        if spheroids:
            _replace(Path(tmp) / CACHE_FILE, out / CACHE_FILE)
        elif (out / CACHE_FILE).exists():
            (out / CACHE_FILE).unlink()
        (Path(tmp) / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
        _replace(Path(tmp) / MANIFEST, out / MANIFEST)
    return manifest


def restore(src_dir: os.PathLike, db: os.PathLike, engine: Optional[str] = None,
            engine_changed_ok: bool = False, cache: Optional[os.PathLike] = None
            ) -> Dict[str, Any]:
    """Puts a saved copy back as the store `db` (which must not exist: nothing is overwritten)
    and its spheroids into the cache folder; returns the manifest. Refuses a copy saved under
    another engine unless engine_changed_ok."""
    src = Path(src_dir)
    db = Path(db)
    if not (src / MANIFEST).is_file() or not (src / DB_FILE).is_file():
        raise StoreCopyError(f"restore-store: {src} holds no saved store ({MANIFEST} and "
                             f"{DB_FILE}; write one with save-store)")
    manifest = json.loads((src / MANIFEST).read_text())
    for p in (db, Path(str(db) + "-wal")):
        if p.exists():
            raise StoreCopyError(f"restore-store: {p} exists; a restore overwrites nothing "
                                 "(move it away, or name another --db)")
    now = engine or engine_id()
    saved = manifest.get("engine", "unknown")
    if saved != now and not engine_changed_ok:
        raise StoreCopyError(
            f"restore-store: the copy was saved under engine {saved}, this checkout's is {now}: "
            "its running jobs would resume from checkpoints the other engine wrote. If the "
            "step's results did not change (bit-identical), pass --engine-changed; otherwise "
            "restore with it and cancel the jobs that were running, or run them anew")
    db.parent.mkdir(parents=True, exist_ok=True)
    tmp = db.with_name(db.name + ".restoring")
    with lzma.open(src / DB_FILE, "rb") as z, tmp.open("wb") as f:
        shutil.copyfileobj(z, f)
    _counts(tmp)  # a readable store, or an error before anything is in place
    os.replace(tmp, db)
    if (src / CACHE_FILE).is_file():
        cache_dir = _cache_dir(db, cache)
        cache_dir.mkdir(parents=True, exist_ok=True)
        with tarfile.open(src / CACHE_FILE, "r:xz") as t:
            for m in t.getmembers():
                # Plain files named without a folder only: a copy is data, not a path to trust.
                if not m.isfile() or "/" in m.name or m.name.startswith("."):
                    raise StoreCopyError(f"restore-store: {CACHE_FILE} holds {m.name!r}, not "
                                         "a prepared spheroid")
                if not (cache_dir / m.name).exists():
                    t.extract(m, cache_dir)
    return manifest
