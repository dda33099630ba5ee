#!/usr/bin/env python3
"""Prometheus (Debian's 2.42) as a real scraper of foamd.

Starts foamd with a token and its HTTP endpoint, and Prometheus with deploy/prometheus.yml's
scrape job pointed at it (the token from a credentials file); then asks Prometheus' HTTP API for
foamd metrics until they arrive. Usage: test_prometheus.py FOAMD REPO_ROOT. Exit 77 (skipped)
when /usr/bin/prometheus is missing.
"""

import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request
from pathlib import Path


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def get(url: str, token: str = "") -> tuple[int, str]:
    req = urllib.request.Request(url)
    if token:
        req.add_header("Authorization", "Bearer " + token)
    try:
        with urllib.request.urlopen(req, timeout=5) as r:
            return r.status, r.read().decode()
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode()


def wait(what: str, pred, timeout_s: float, procs) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for name, p in procs:
            if p.poll() is not None:
                raise SystemExit(f"FAIL: {name} exited ({p.returncode}) while waiting for {what}")
        try:
            if pred():
                return
        except OSError:
            pass
        time.sleep(0.25)
    raise SystemExit(f"FAIL: timed out waiting for {what}")


def main() -> int:
    prometheus = shutil.which("prometheus") or "/usr/bin/prometheus"
    if not os.access(prometheus, os.X_OK):
        print("SKIPPED: prometheus is not installed (apt-get install prometheus)")
        return 77
    foamd, root = sys.argv[1], Path(sys.argv[2])
    tmp = Path(tempfile.mkdtemp(prefix="foam-prom-"))
    token = os.urandom(16).hex()
    (tmp / "token").write_text(token + "\n")
    (tmp / "token").chmod(0o600)
    gport, hport, pport = free_port(), free_port(), free_port()
    # deploy/prometheus.yml, pointed at this foamd and its token, scraping every second.
    config = (root / "deploy" / "prometheus.yml").read_text()
    assert "127.0.0.1:8080" in config and "/etc/activefoam/token" in config, "deploy file changed"
    config = (config.replace("127.0.0.1:8080", f"127.0.0.1:{hport}")
              .replace("/etc/activefoam/token", str(tmp / "token"))
              .replace("scrape_interval: 15s", "scrape_interval: 1s"))
    (tmp / "prometheus.yml").write_text(config)
    procs = []
    try:
        log = (tmp / "foamd.log").open("w")
        procs.append(("foamd", subprocess.Popen(
            [foamd, "--listen", f"127.0.0.1:{gport}", "--http", f"127.0.0.1:{hport}",
             "--db", str(tmp / "f.db"), "--workers", "3", "--token-file", str(tmp / "token")],
            stdout=log, stderr=subprocess.STDOUT)))
        base = f"http://127.0.0.1:{hport}"
        wait("foamd's /healthz", lambda: get(base + "/healthz")[0] == 200, 20, procs)
        code, _ = get(base + "/metrics")
        assert code == 401, f"/metrics without the token answered {code}"
        print("ok: foamd's /metrics needs the token")
        plog = (tmp / "prometheus.log").open("w")
        procs.append(("prometheus", subprocess.Popen(
            [prometheus, "--config.file", str(tmp / "prometheus.yml"),
             "--storage.tsdb.path", str(tmp / "tsdb"),
             "--web.listen-address", f"127.0.0.1:{pport}"],
            stdout=plog, stderr=subprocess.STDOUT)))
        api = f"http://127.0.0.1:{pport}/api/v1/query?query="
        result = {}

        def answered() -> bool:
            code, body = get(api + urllib.parse.quote("foamd_workers"))
            if code != 200:
                return False
            data = json.loads(body)["data"]["result"]
            if data:
                result.update(data[0])
            return bool(data)

        wait("foamd_workers through Prometheus' API", answered, 60, procs)
        assert result["metric"]["job"] == "foamd", result
        assert float(result["value"][1]) == 3, f"foamd_workers = {result['value'][1]}, expected 3"
        print(f"ok: Prometheus scraped foamd_workers = {result['value'][1]} "
              f"(instance {result['metric']['instance']})")
        code, body = get(api + urllib.parse.quote('up{job="foamd"}'))
        assert json.loads(body)["data"]["result"][0]["value"][1] == "1", body
        code, body = get(api + urllib.parse.quote('foamd_jobs{state="JOB_STATE_QUEUED"}'))
        assert json.loads(body)["data"]["result"][0]["value"][1] == "0", body
        print("ok: up = 1 and foamd_jobs{state=\"JOB_STATE_QUEUED\"} = 0")
        return 0
    finally:
        for name, p in reversed(procs):
            p.terminate()
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
        if os.environ.get("KEEP_TMP"):
            print("kept", tmp)
        else:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
