"""A real foamd per test module (FOAMD_EXE, set by ctest), on a free loopback port."""

import os
import socket
import subprocess
import time
from pathlib import Path

import pytest

from activefoam import Client


# A fusion of 2 × 4 cells that prepares and runs in seconds: the base spec of the study tests.
TINY_FUSION = """\
scene = "fusion"
sample_every_s = 30
snapshot_every_s = 0
[numerics]
dt_s = 0.5
[scene]
n_cells = 4
prep_max_s = 300
allow_uncompacted = true
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Foamd:
    def __init__(self, tmp: Path, token: str = "", extra_args=()):
        exe = os.environ.get("FOAMD_EXE")
        if not exe or not Path(exe).exists():
            pytest.skip("FOAMD_EXE does not name a built foamd (ctest sets it)")
        self.address = f"127.0.0.1:{_free_port()}"
        self.log = tmp / "foamd.log"
        args = [exe, "--listen", self.address, "--db", str(tmp / "foamd.db"), "--workers", "2",
                *extra_args]
        if token:
            token_file = tmp / "token"
            token_file.write_text(token + "\n")
            token_file.chmod(0o600)
            args += ["--token-file", str(token_file)]
        self.proc = subprocess.Popen(args, stdout=self.log.open("w"), stderr=subprocess.STDOUT)
        client = Client(self.address, token=token or None, timeout_s=5)
        deadline = time.monotonic() + 20
        while True:
            try:
                client.jobs()
                break
            except Exception:  # not listening yet
                if self.proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError("foamd did not start:\n" + self.log.read_text())
                time.sleep(0.1)
        client.close()

    def kill(self) -> None:
        """As a machine that goes away: no shutdown, no checkpoint at the end."""
        self.proc.kill()
        self.proc.wait()

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()


@pytest.fixture(scope="module")
def foamd(tmp_path_factory):
    d = Foamd(tmp_path_factory.mktemp("foamd"))
    yield d
    d.stop()


@pytest.fixture(scope="module")
def client(foamd):
    with Client(foamd.address) as c:
        yield c
