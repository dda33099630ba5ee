#!/usr/bin/python3
"""What `foamd --check-db` (SQLite's integrity_check) costs on a large store, against the
quick_check foamd runs at every start.

Makes a store: foamd creates its schema on a new database and stops; then JOBS finished jobs are
written into it the way foamd stores them (a resolved spec each, SAMPLES samples of 20 values
with their events, 30 results, SNAPSHOTS snapshots of 100 KiB of incompressible bytes, as zlib
meshes are), in one transaction per 100 jobs. Then times, with the file in the page cache as
foamd would find it after running:
  quick_check   PRAGMA quick_check through Python's sqlite3 (the same system SQLite): the start
  check-db      foamd --check-db --db STORE (PRAGMA integrity_check, its one line)
Prints the rows of each table, the file's size and the seconds of each.

  bench/check_db_cost.py [BUILD_DIR (build/release)] [JOBS (2000)] [SAMPLES (1440)]
                         [SNAPSHOTS (4)]
"""
import os
import random
import shutil
import socket
import sqlite3
import struct
import subprocess
import sys
import tempfile
import time


def main():
    build = sys.argv[1] if len(sys.argv) > 1 else "build/release"
    jobs = int(sys.argv[2]) if len(sys.argv) > 2 else 2000
    samples = int(sys.argv[3]) if len(sys.argv) > 3 else 1440
    snapshots = int(sys.argv[4]) if len(sys.argv) > 4 else 4
    foamd = os.path.join(build, "server", "foamd")
    tmp = tempfile.mkdtemp(prefix="foam-check-db-cost-")
    db = os.path.join(tmp, "foamd.db")
    try:
        # The schema, as foamd makes it (stopped once it listens).
        with socket.socket() as sock:
            sock.bind(("127.0.0.1", 0))
            port = sock.getsockname()[1]
        server = subprocess.Popen([foamd, "--db", db, "--listen", f"127.0.0.1:{port}",
                                   "--workers", "1", "--log-level", "warn"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        for _ in range(300):
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                time.sleep(0.1)
        server.terminate()
        server.wait(timeout=30)
        # A resolved spec as a job stores it: a committed run's spec.json.
        here = os.path.dirname(os.path.abspath(__file__))
        spec = open(os.path.join(here, "..", "docs", "study", "fusion-ros2", "runs", "standard",
                                 "spec.json")).read()
        rng = random.Random(1)
        con = sqlite3.connect(db)
        con.execute("PRAGMA journal_mode=WAL")
        t0 = time.monotonic()
        for j in range(jobs):
            if j % 100 == 0:
                con.execute("BEGIN")
            jid = f"j-{j:012x}"
            con.execute(
                "INSERT INTO jobs(id, state, scene, seed, tag, spec_json, engine_version, "
                "created_utc, columns_json, outcome) VALUES (?,?,?,?,?,?,?,?,?,?)",
                (jid, 3, "fusion", j, f"study:cost-{j % 7}", spec, "0.1.0",
                 "2026-01-01T00:00:00Z", "[]", "fused"))
            for i in range(samples):
                vals = struct.pack("<20d", *(rng.random() for _ in range(20)))
                con.execute("INSERT INTO samples(job_id, idx, t_s, vals) VALUES (?,?,?,?)",
                            (jid, i, 60.0 * i, vals))
                con.execute("INSERT INTO events(job_id, seq, time_utc, data) VALUES (?,?,?,?)",
                            (jid, i + 1, "2026-01-01T00:00:00Z", vals[:96]))
            for k in range(30):
                con.execute("INSERT INTO results(job_id, name, value) VALUES (?,?,?)",
                            (jid, f"metric_{k}", rng.random()))
            for k in range(snapshots):
                con.execute(
                    "INSERT INTO snapshots(job_id, idx, t_s, step, bytes, vertices, triangles, "
                    "compression, data) VALUES (?,?,?,?,?,?,?,?,?)",
                    (jid, k, 3600.0 * k, k * 100, 100 << 10, 1000, 2000, "zlib",
                     rng.randbytes(100 << 10)))
            if j % 100 == 99 or j == jobs - 1:
                con.execute("COMMIT")
        con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        rows = {t: con.execute(f"SELECT count(*) FROM {t}").fetchone()[0]
                for t in ("jobs", "samples", "events", "results", "snapshots")}
        con.close()
        made = time.monotonic() - t0
        size = os.path.getsize(db)
        print(f"store: {size / 2**20:.0f} MiB, {sum(rows.values())} rows ("
              + ", ".join(f"{t} {n}" for t, n in rows.items()) + f"), written in {made:.0f} s")
        t0 = time.monotonic()
        con = sqlite3.connect(db)
        quick = con.execute("PRAGMA quick_check").fetchone()[0]
        con.close()
        print(f"quick_check (foamd's start): {quick}, {time.monotonic() - t0:.1f} s")
        t0 = time.monotonic()
        r = subprocess.run([foamd, "--check-db", "--db", db], capture_output=True, text=True)
        print(f"foamd --check-db: exit {r.returncode}, {time.monotonic() - t0:.1f} s: "
              f"{(r.stdout + r.stderr).strip()}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
