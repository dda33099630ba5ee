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
from typing import Any, Dict, List, Optional

from activefoam.inputs import read_bounded

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
    try:
        out.mkdir(parents=True, exist_ok=True)
        return _save(db, out, engine, cache, snapshots, engine_commit)
    except OSError as e:  # a full disk, a read-only folder: the earlier copy stays whole
        raise StoreCopyError(f"save-store: cannot write into {out}: "
                             f"{e.strerror or e}") from None


def _save(db: Path, out: Path, engine: Optional[str], cache: Optional[os.PathLike],
          snapshots: bool, engine_commit: str) -> Dict[str, Any]:
    with tempfile.TemporaryDirectory(dir=out) as tmp:
        copy = Path(tmp) / "store.db"
        src = sqlite3.connect(str(db), timeout=2)
        dst = sqlite3.connect(str(copy))
        try:
            src.backup(dst)
        except sqlite3.DatabaseError as e:
            # foamd's hold shows as locked, busy or a locking protocol error; a full disk or
            # a file that is no database is no foamd.
            if not any(w in str(e) for w in ("lock", "busy", "protocol")):
                raise StoreCopyError(f"save-store: cannot copy {db} into {out}: {e}") from None
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


def _manifest(path: Path) -> Dict[str, Any]:
    try:
        manifest = json.loads(read_bounded(path, 1 << 20, MANIFEST, regular=True))
    except ValueError as e:  # a bounded read's refusal, or not JSON
        raise StoreCopyError(f"restore-store: {path}: {e}") from None
    if not isinstance(manifest, dict):
        raise StoreCopyError(f"restore-store: {path}: not a manifest (a JSON object)")
    return manifest


def _damaged(path: Path, e: BaseException) -> StoreCopyError:
    return StoreCopyError(f"restore-store: {path} is damaged ({type(e).__name__}: {e}); nothing "
                          "was restored")


def _no_room(path: Path, where: Path, e: OSError) -> StoreCopyError:
    return StoreCopyError(f"restore-store: cannot unpack {path} into {where}: "
                          f"{e.strerror or e}; nothing was restored")


class _Budget:
    """The bytes the archives may still unpack to: an xz bomb stops at the bound, not at a full
    disk."""

    def __init__(self, limit: int) -> None:
        self.limit, self.left = limit, limit

    def take(self, n: int, path: Path) -> None:
        self.left -= n
        if self.left < 0:
            size = (f"{self.limit / 2**30:g} GiB" if self.limit >= 2**30
                    else f"{self.limit / 2**20:g} MiB")
            raise StoreCopyError(
                f"restore-store: {path} unpacks to more than the {size} a restore may unpack "
                "(--max-unpacked-gib); nothing was restored")


def _unpack_db(src: Path, dst: Path, budget: _Budget) -> None:
    try:
        with lzma.open(src, "rb") as z, open(dst, "xb") as f:
            while True:
                try:
                    chunk = z.read(1 << 20)
                except (lzma.LZMAError, EOFError, OSError) as e:
                    raise _damaged(src, e) from None
                if not chunk:
                    break
                budget.take(len(chunk), src)
                f.write(chunk)
    except OSError as e:  # writing: a full disk, a read-only folder
        raise _no_room(src, dst.parent.parent, e) from None


def _check_store(src: Path, path: Path) -> Dict[str, Any]:
    """The store's counts, after SQLite's integrity_check (read-only: the copy is not touched)."""
    try:
        con = sqlite3.connect(path.resolve().as_uri() + "?mode=ro", uri=True)
        try:
            rows = con.execute("PRAGMA integrity_check(10)").fetchall()
            problems = [ln for r in rows for ln in str(r[0]).splitlines()
                        if not ln.startswith("***")]
            if problems != ["ok"]:
                raise StoreCopyError(f"restore-store: {src} holds a damaged store "
                                     f"(integrity_check: {problems[0][:200]}"
                                     + (", and more" if len(problems) > 1 else "")
                                     + "); nothing was restored")
        finally:
            con.close()
        return _counts(path)
    except sqlite3.DatabaseError as e:
        raise StoreCopyError(f"restore-store: {src} holds no foamd store ({e}); nothing was "
                             "restored") from None


MAX_SPHEROIDS = 100000


def _unpack_spheroids(src: Path, stage: Path, budget: _Budget) -> List[str]:
    """The archive's files, unpacked into `stage`: plain files named without a folder only (a
    copy is data, not a path to trust)."""
    names: List[str] = []
    try:
        with tarfile.open(src, "r:xz") as t:
            for m in t:
                if (not m.isfile() or not m.name or "/" in m.name or m.name.startswith(".")
                        or len(m.name.encode()) > 255 or m.name in names):
                    raise StoreCopyError(f"restore-store: {src} holds {m.name!r}, not a "
                                         "prepared spheroid; nothing was restored")
                if len(names) >= MAX_SPHEROIDS:
                    raise StoreCopyError(f"restore-store: {src} holds more than "
                                         f"{MAX_SPHEROIDS} files; nothing was restored")
                budget.take(m.size, src)
                data = t.extractfile(m)
                assert data is not None  # a regular file
                try:
                    with open(stage / m.name, "xb") as f:
                        shutil.copyfileobj(data, f, 1 << 20)
                except OSError as e:
                    raise _no_room(src, stage.parent, e) from None
                names.append(m.name)
            # To the xz stream's end: a cut archive whose members are whole fails its check
            # here (tar itself takes a missing end block for the end).
            while True:
                rest = t.fileobj.read(1 << 20)  # type: ignore[union-attr]
                if not rest:
                    break
                budget.take(len(rest), src)
    except (tarfile.TarError, lzma.LZMAError, EOFError) as e:
        raise _damaged(src, e) from None
    except OSError as e:  # reading the archive
        raise _damaged(src, e) from None
    return names


def _make_dirs(path: Path) -> List[Path]:
    """mkdir -p, returning the folders it made (outermost first), to remove on a failure."""
    made: List[Path] = []
    for d in reversed([path, *path.parents]):
        if not d.exists():
            d.mkdir()
            made.append(d)
    return made


def _place(tmp: Path, db: Path) -> None:
    try:
        os.link(tmp, db)  # never over a store that appeared meanwhile
    except FileExistsError:
        raise StoreCopyError(f"restore-store: {db} exists; a restore overwrites nothing") from None
    except OSError:  # a file system without hard links
        if db.exists():
            raise StoreCopyError(f"restore-store: {db} exists; a restore overwrites "
                                 "nothing") from None
        os.replace(tmp, db)


MAX_UNPACKED_BYTES = 20 << 30


def restore(src_dir: os.PathLike, db: os.PathLike, engine: Optional[str] = None,
            engine_changed_ok: bool = False, cache: Optional[os.PathLike] = None,
            max_unpacked: int = MAX_UNPACKED_BYTES) -> Dict[str, Any]:
    """Puts a saved copy back as the store `db` (which must not exist: nothing is overwritten)
    and its spheroids into the cache folder; returns the manifest. Refuses a copy saved under
    another engine unless engine_changed_ok.

    All or nothing: both archives are unpacked next to their destinations first (at most
    `max_unpacked` bytes together), the store checked by SQLite's integrity_check and against
    the manifest's counts, the spheroid archive's members checked to be plain files without a
    folder; only then is anything put in place, the store last. On any failure StoreCopyError
    names the file and nothing is left behind."""
    src = Path(src_dir)
    db = Path(db)
    if not (src / MANIFEST).is_file() or not (src / DB_FILE).is_file():
        raise StoreCopyError(f"restore-store: {src} holds no saved store ({MANIFEST} and "
                             f"{DB_FILE}; write one with save-store)")
    manifest = _manifest(src / MANIFEST)
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
    cache_dir = _cache_dir(db, cache)
    made: List[Path] = []
    stages: List[Path] = []
    added: List[Path] = []
    done = False
    try:
        made += _make_dirs(db.parent)
        budget = _Budget(max_unpacked)
        stages.append(Path(tempfile.mkdtemp(prefix=f".{db.name}.restoring-", dir=db.parent)))
        tmp_db = stages[0] / "store.db"
        _unpack_db(src / DB_FILE, tmp_db, budget)
        counts = _check_store(src / DB_FILE, tmp_db)
        for key in ("jobs", "checkpoints"):
            if isinstance(manifest.get(key), int) and manifest[key] != counts[key]:
                raise StoreCopyError(f"restore-store: {src / DB_FILE} holds {counts[key]} "
                                     f"{key}, {src / MANIFEST} says {manifest[key]}: not the "
                                     "copy the manifest describes; nothing was restored")
        names: List[str] = []
        if (src / CACHE_FILE).is_file():
            made += _make_dirs(cache_dir.parent)
            stages.append(Path(tempfile.mkdtemp(prefix=".spheroids.restoring-",
                                                dir=cache_dir.parent)))
            names = _unpack_spheroids(src / CACHE_FILE, stages[-1], budget)
            if isinstance(manifest.get("spheroids"), int) and manifest["spheroids"] != len(names):
                raise StoreCopyError(f"restore-store: {src / CACHE_FILE} holds {len(names)} "
                                     f"files, {src / MANIFEST} says {manifest['spheroids']} "
                                     "prepared spheroids; nothing was restored")
        # Everything is checked: into place, the store last (foamd started on a store finds
        # its spheroids).
        if names:
            made += _make_dirs(cache_dir)
            for n in names:
                if not (cache_dir / n).exists():
                    os.replace(stages[-1] / n, cache_dir / n)
                    added.append(cache_dir / n)
        _place(tmp_db, db)
        done = True
    except OSError as e:
        raise StoreCopyError(f"restore-store: {e.filename or db.parent}: {e.strerror or e}; "
                             "nothing was restored") from None
    finally:
        for d in stages:
            shutil.rmtree(d, ignore_errors=True)
        if not done:
            for f in added:
                f.unlink(missing_ok=True)
            for d in reversed(made):
                try:
                    d.rmdir()
                except OSError:
                    pass
    return manifest
