#!/usr/bin/env python3
"""`pip install ./python` into a fresh virtual environment, then a sweep and a study through a
real foamd with the installed package alone (no source tree on the path, no C++ build).

    FOAMD_EXE=build/release/server/foamd /usr/bin/python3 tests/python/pip_install_sweep.py

Offline, the environment sees Debian's python3-grpcio, -protobuf, -pandas and -matplotlib
(--system-site-packages) and pip builds with Debian's setuptools (--no-build-isolation,
--no-index): the command python/README.md gives. Exit 0 passed, 1 failed, 77 skipped (no
`python3 -m venv`: Debian's python3-venv).
"""

import importlib.util
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# The client's checks run inside the environment: everything they import is the installed copy.
SWEEP = textwrap.dedent("""\
    import sys, time
    import activefoam
    from activefoam import Client
    assert activefoam.__file__.startswith(sys.prefix), activefoam.__file__
    c = Client(sys.argv[1], timeout_s=5)
    deadline = time.monotonic() + 20
    while True:
        try:
            c.jobs()
            break
        except ConnectionError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)
    tiny = {"scene": "cell", "duration_s": 5, "sample_every_s": 1, "snapshot_every_s": 0,
            "numerics": {"triangles_per_cell": 80}}
    sw = c.sweep(tiny, grid={"cells.gamma": [0.4, 0.6]}, seeds=[1], tags=["pip-install"])
    assert sw.wait(timeout_s=300) == {"succeeded": 2}, sw.wait()
    table = sw.results(metrics=["aspect_ratio", "wall_s"])
    assert sorted(table["cells.gamma"]) == [0.4, 0.6], table
    assert (table["state"] == "succeeded").all() and table["aspect_ratio"].notna().all(), table
    samples = c.job(table["job_id"][0]).samples()
    assert samples["t_s"].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0], samples
    print(f"sweep: {len(table)} jobs succeeded with results ({activefoam.__file__})")
    """)

STUDY = textwrap.dedent("""\
    [study]
    name = "installed"
    seeds = [1]
    x = "cells.alpha"
    [spec]
    scene = "fusion"
    duration_s = 240
    sample_every_s = 30
    snapshot_every_s = 0
    "numerics.dt_s" = 0.5
    "scene.n_cells" = 4
    "scene.prep_max_s" = 300
    "scene.allow_uncompacted" = true
    [[grid]]
    "cells.alpha" = [0.4375, 0.6]
    """)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _has_venv() -> bool:
    # Debian's python3 leaves ensurepip to python3-venv.
    return all(importlib.util.find_spec(m) is not None for m in ("ensurepip", "venv"))


def _run(args, **kw) -> subprocess.CompletedProcess:
    r = subprocess.run(args, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"FAILED: {' '.join(map(str, args))} (exit {r.returncode}):\n{r.stdout}{r.stderr}")
    return r


def main() -> int:
    foamd = os.environ.get("FOAMD_EXE", "")
    if not foamd or not Path(foamd).is_file():
        print("FOAMD_EXE does not name a built foamd (ctest sets it)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="pip-install-") as tmp:
        tmp = Path(tmp)
        # The package as a clean checkout holds it: pip builds in the source folder, and this
        # test leaves the working tree as it found it.
        src = tmp / "python"
        shutil.copytree(ROOT / "python", src, ignore=shutil.ignore_patterns(
            "tests", "build", "*.egg-info", "__pycache__"))
        venv = tmp / "venv"
        r = subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)],
                           capture_output=True, text=True)
        if r.returncode != 0:
            if "ensurepip is not available" in " ".join((r.stdout + r.stderr).split()) \
                    or not _has_venv():
                print(f"SKIPPED: {sys.executable} -m venv is not available (Debian: apt-get "
                      f"install python3-venv):\n{r.stdout}{r.stderr}")
                return 77
            sys.exit(f"FAILED: python3 -m venv:\n{r.stdout}{r.stderr}")
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        env["PYTHONDONTWRITEBYTECODE"] = "1"
        py, bin_dir = venv / "bin" / "python", venv / "bin"
        _run([py, "-m", "pip", "install", "--no-build-isolation", "--no-index", str(src)],
             env=env, cwd=tmp, timeout=300)
        shutil.rmtree(src)  # the installed copy alone from here on
        log = tmp / "foamd.log"
        address = f"127.0.0.1:{_free_port()}"
        server = subprocess.Popen([foamd, "--listen", address, "--db", str(tmp / "foamd.db"),
                                   "--workers", "2"], stdout=log.open("w"),
                                  stderr=subprocess.STDOUT, env=dict(env, OMP_NUM_THREADS="1"))
        try:
            r = subprocess.run([py, "-c", SWEEP, address], capture_output=True, text=True,
                               env=env, cwd=tmp, timeout=400)
            if r.returncode != 0:
                sys.exit(f"FAILED: the sweep:\n{r.stdout}{r.stderr}\nfoamd:\n{log.read_text()}")
            print(r.stdout, end="")
            # The study tool through its console script: submit, wait, report.
            (tmp / "installed.toml").write_text(STUDY)
            r = subprocess.run([bin_dir / "foam-study", "run", "installed.toml", "--report",
                                "report"], capture_output=True, text=True,
                               env=dict(env, FOAM_SERVER=address), cwd=tmp, timeout=400)
            if r.returncode != 0:
                sys.exit(f"FAILED: foam-study run (exit {r.returncode}):\n{r.stdout}{r.stderr}"
                         f"\nfoamd:\n{log.read_text()}")
            summary = (tmp / "report" / "summary.csv").read_text().splitlines()
            if len(summary) != 3:
                sys.exit(f"FAILED: foam-study's summary.csv has {len(summary) - 1} points:\n"
                         + "\n".join(summary))
            written = ", ".join(sorted(p.name for p in (tmp / "report").iterdir()))
            print(f"foam-study: 2 runs succeeded, report {written}")
        finally:
            server.terminate()
            try:
                server.wait(timeout=20)
            except subprocess.TimeoutExpired:
                server.kill()
    print("passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
