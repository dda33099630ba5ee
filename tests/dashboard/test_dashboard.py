#!/usr/bin/python3
"""Acceptance test of foamd's browser dashboard, in headless Chromium.

A real foamd (env FOAMD) with a bearer token runs two small jobs and a four-job sweep submitted
by the foam CLI (env FOAM); the test then opens the dashboard foamd serves and checks the
rendered DOM: the token prompt, the job list, a job's chart against its samples, the samples
download, and the sweep page. With SCREENSHOT_DIR set it saves dashboard-jobs.png,
dashboard-job.png and dashboard-sweep.png there (1280x900).

Exit status: 0 passed, 1 failed, 2 misconfigured, 77 skipped (no usable /usr/bin/chromium).
Standard library only; run it as  FOAMD=... FOAM=... /usr/bin/python3 test_dashboard.py
"""

import json
import math
import os
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from pathlib import Path

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, str(Path(__file__).resolve().parent))
import cdp  # noqa: E402

SKIP = 77
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
TERMINAL = {"succeeded", "failed", "cancelled"}
WIDTH, HEIGHT = 1280, 900


def say(message: str) -> None:
    print(message, flush=True)


def check(condition, message: str) -> None:
    if not condition:
        raise AssertionError(message)
    say(f"  ok  {message}")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Foamd:
    def __init__(self, exe: str, foam: str, tmp: Path):
        self.foam_exe = foam
        self.token = secrets.token_hex(16)
        self.token_file = tmp / "token"
        fd = os.open(self.token_file, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(self.token + "\n")
        self.address = f"127.0.0.1:{free_port()}"
        self.base = f"http://127.0.0.1:{free_port()}"
        self.log = tmp / "foamd.log"
        args = [exe, "--listen", self.address, "--db", str(tmp / "f.db"), "--workers", "2",
                "--http", self.base.removeprefix("http://"), "--token-file", str(self.token_file)]
        say("starting " + " ".join(args))
        with self.log.open("w") as log:
            self.proc = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + 30
        while True:
            try:
                if self.get("/healthz", token=False)[0] == 200:
                    break
            except OSError:
                pass
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise AssertionError("foamd did not start:\n" + self.log_tail())
            time.sleep(0.1)

    def log_tail(self, n: int = 3000) -> str:
        try:
            return self.log.read_text(errors="replace")[-n:]
        except OSError:
            return ""

    def get(self, path: str, token: bool = True):
        """(status, content type, body bytes) of a GET on foamd's HTTP port."""
        req = urllib.request.Request(self.base + path)
        if token:
            req.add_header("Authorization", f"Bearer {self.token}")
        try:
            with urllib.request.urlopen(req, timeout=10) as r:
                return r.status, r.headers.get("Content-Type", ""), r.read()
        except urllib.error.HTTPError as e:
            return e.code, e.headers.get("Content-Type", ""), e.read()

    def json(self, path: str):
        status, _, body = self.get(path)
        if status != 200:
            raise AssertionError(f"GET {path}: HTTP {status}: {body[:300]!r}")
        return json.loads(body)

    def foam(self, *args: str) -> str:
        cmd = [self.foam_exe, "--server", self.address, "--token-file", str(self.token_file), *args]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        if r.returncode != 0:
            raise AssertionError(f"{' '.join(cmd)} exited {r.returncode}:\n{r.stdout}{r.stderr}")
        return r.stdout

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def wait_done(foamd: Foamd, job_ids, timeout_s: float = 300) -> None:
    deadline = time.monotonic() + timeout_s
    pending = list(job_ids)
    while pending:
        pending = [j for j in pending if foamd.foam("show", j).splitlines()[0].strip() not in TERMINAL]
        if pending and time.monotonic() > deadline:
            raise AssertionError(f"jobs still not done after {timeout_s} s: {pending}")
        if pending:
            time.sleep(0.5)
    for j in job_ids:
        state = foamd.foam("show", j).splitlines()[0].strip()
        check(state == "succeeded", f"job {j} {state}")


def js(value) -> str:
    return json.dumps(value)


def rows_of(page) -> dict:
    """{job id: state text} of the job table's rows."""
    return page.evaluate(
        "Object.fromEntries([...document.querySelectorAll('#jobs tr[data-job-id]')]"
        ".map(r => [r.dataset.jobId, r.querySelector('.state').textContent.trim()]))")


def screenshot(page, name: str) -> None:
    out = os.environ.get("SCREENSHOT_DIR")
    if not out:
        return
    os.makedirs(out, exist_ok=True)
    time.sleep(0.3)  # let the last layout settle
    page.screenshot(os.path.join(out, name), WIDTH, HEIGHT)
    say(f"  --  screenshot {os.path.join(out, name)}")


def column_points(samples: dict, column: str):
    t, y = samples["columns"].index("t_s"), samples["columns"].index(column)
    return [[r[t], r[y]] for r in samples["rows"]
            if isinstance(r[t], (int, float)) and isinstance(r[y], (int, float))
            and math.isfinite(r[t]) and math.isfinite(r[y])]


def same_points(got, want) -> bool:
    return len(got) == len(want) and all(
        math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-300) for p, q in zip(got, want) for a, b in zip(p, q))


def median(values):
    v = sorted(values)
    n = len(v)
    return v[n // 2] if n % 2 else (v[n // 2 - 1] + v[n // 2]) / 2


def wait_download(directory: Path, name: str, timeout_s: float = 15) -> bytes:
    path = directory / name
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        partial = list(directory.glob("*.crdownload"))
        if path.exists() and not partial:
            return path.read_bytes()
        time.sleep(0.1)
    raise AssertionError(f"{name} was not downloaded (in {directory}: {sorted(os.listdir(directory))})")


def run(foamd: Foamd, browser: cdp.Browser, tmp: Path) -> None:
    base = foamd.base

    say("foamd's routes:")
    status, ctype, body = foamd.get("/", token=False)
    check(status == 200 and ctype.startswith("text/html"), f"/ without a token: {status} {ctype}")
    for asset in ("/app.js", "/style.css", "/chart.js"):
        status, ctype, _ = foamd.get(asset, token=False)
        check(status == 200, f"{asset} without a token: {status} {ctype}")
    status, _, body = foamd.get("/jobs", token=False)
    check(status == 401 and "error" in json.loads(body), f"/jobs without a token: {status} {body[:80]!r}")

    say("submitting jobs:")
    cell = foamd.foam("submit", str(EXAMPLES / "cell.toml"), "--tag", "dash",
                      "--set", "duration_s=30").splitlines()[0].strip()
    doublet = foamd.foam("submit", str(EXAMPLES / "doublet.toml"), "--tag", "dash",
                         "--set", "duration_s=60", "--set", "sample_every_s=10").splitlines()[0].strip()
    sweep = foamd.foam("sweep", str(EXAMPLES / "doublet.toml"), "--grid", "cells.alpha=0.3,0.6",
                       "--seeds", "1", "2", "--set", "duration_s=60", "--set", "sample_every_s=10",
                       "--tag", "dash-sweep").splitlines()[0].strip()
    say(f"  cell {cell}, doublet {doublet}, sweep {sweep}")
    sweep_jobs = []
    deadline = time.monotonic() + 30
    while len(sweep_jobs) < 4 and time.monotonic() < deadline:
        sweep_jobs = [j["id"] for j in foamd.json(f"/jobs?sweep={sweep}")["jobs"]]
        time.sleep(0.2)
    check(len(sweep_jobs) == 4, f"the sweep has 4 jobs: {sweep_jobs}")
    wait_done(foamd, [cell, doublet, *sweep_jobs])

    say("(1) / without a token: the prompt, then the jobs")
    page = browser.new_page(WIDTH, HEIGHT)
    page.navigate(base + "/")
    page.wait_for("!document.querySelector('#token-prompt').hidden")
    check(page.evaluate("!document.querySelector('#token-prompt').hidden"), "the token prompt shows")
    check(page.evaluate("document.querySelectorAll('tr[data-job-id]').length") == 0, "no job rows")
    check(page.evaluate("!!document.querySelector('#token-prompt input#token-input')"
                        " && document.querySelector('#token-submit').form?.id === 'token-prompt'"),
          "the prompt is a form with input#token-input and #token-submit")
    page.insert_text("#token-input", foamd.token)
    page.evaluate("document.querySelector('#token-submit').click()")
    page.wait_for(f"(() => {{ const r = document.querySelectorAll('#jobs tr[data-job-id]');"
                  f" return [...r].some(x => x.dataset.jobId === {js(cell)})"
                  f" && [...r].some(x => x.dataset.jobId === {js(doublet)}); }})()")
    rows = rows_of(page)
    check(rows.get(cell) == "succeeded" and rows.get(doublet) == "succeeded",
          f"both jobs listed as succeeded: {cell}={rows.get(cell)}, {doublet}={rows.get(doublet)}")
    check(page.evaluate("document.querySelector('#token-prompt').hidden"), "the prompt is gone")
    page.close()

    say("(2) /#token=TOKEN: the jobs, and the fragment leaves the address")
    page = browser.new_page(WIDTH, HEIGHT)  # a new tab: empty sessionStorage
    page.navigate(f"{base}/#token={foamd.token}")
    page.wait_for("document.querySelectorAll('#jobs tr[data-job-id]').length >= 6")
    rows = rows_of(page)
    check(all(rows.get(j) == "succeeded" for j in [cell, doublet, *sweep_jobs]),
          f"all six jobs listed as succeeded ({len(rows)} rows)")
    href = page.evaluate("location.href")
    check(foamd.token not in href and page.evaluate("location.hash") == "#/", f"the address is now {href}")
    check(page.evaluate("document.querySelector('#token-prompt').hidden"), "no token prompt")
    row = f"document.querySelector('#jobs tr[data-job-id={js(doublet)}]')"
    check(page.evaluate(f"{row}.querySelector('a[href=\"#/job/{doublet}\"]') !== null"
                        f" && {row}.querySelector('progress') !== null"),
          "the doublet's row links to its page and has a progress bar")
    screenshot(page, "dashboard-jobs.png")

    say("(3) the doublet's page: its chart holds its samples")
    samples = foamd.json(f"/jobs/{doublet}/samples")
    want = column_points(samples, "contact_angle_deg")
    page.navigate(f"{base}/#/job/{doublet}")
    page.wait_for(f"document.querySelector('#job-id')?.textContent === {js(doublet)}"
                  " && document.querySelector('canvas#main-chart')?.dataset.points")
    got = json.loads(page.evaluate("document.querySelector('canvas#main-chart').dataset.points"))
    check(page.evaluate("document.querySelector('canvas#main-chart').dataset.column") == "contact_angle_deg",
          "the main chart shows contact_angle_deg")
    check(len(want) >= 7, f"the doublet has {len(want)} samples of contact_angle_deg")
    check(same_points(got, want), f"the chart's {len(got)} (t, y) points equal /jobs/{doublet}/samples")
    check(page.evaluate("document.querySelector('#job-state').textContent") == "succeeded", "state succeeded")
    check(page.evaluate("!!document.querySelector('canvas#health-chart')"), "the solver health chart exists")
    spec = json.loads(page.evaluate("document.querySelector('pre#job-spec').textContent"))
    check(spec.get("scene", {}).get("kind") == "doublet" and spec.get("duration_s") == 60,
          "pre#job-spec holds the resolved spec")
    results = page.evaluate("Object.fromEntries([...document.querySelectorAll('#results tbody tr')]"
                            ".map(r => [r.cells[0].textContent, r.cells[1].textContent]))")
    check("contact_angle_deg" in results, f"table#results lists {len(results)} results")
    check(page.evaluate("document.querySelector('a#samples-csv').getAttribute('href')")
          .endswith(f"jobs/{doublet}/samples.csv"), "a#samples-csv points at samples.csv")
    check(page.evaluate("document.querySelector('a#vtk-export').getAttribute('href')")
          .endswith(f"jobs/{doublet}/snapshots/latest.vtp"), "a#vtk-export points at latest.vtp")

    downloads = tmp / "downloads"
    downloads.mkdir()
    browser.send("Browser.setDownloadBehavior", {"behavior": "allow", "downloadPath": str(downloads)})
    page.evaluate("document.querySelector('a#samples-csv').click()")
    csv = wait_download(downloads, f"{doublet}-samples.csv")
    status, ctype, server_csv = foamd.get(f"/jobs/{doublet}/samples.csv")
    check(status == 200 and csv == server_csv and csv.decode().splitlines()[0] == ",".join(samples["columns"]),
          f"a#samples-csv downloads {doublet}-samples.csv with the token ({len(csv)} bytes, {ctype})")
    page.evaluate("document.querySelector('a#vtk-export').click()")
    vtp = wait_download(downloads, f"{doublet}-latest.vtp")
    check(b"<VTKFile" in vtp[:400] and b"PolyData" in vtp[:400],
          f"a#vtk-export downloads {doublet}-latest.vtp ({len(vtp)} bytes)")
    check(page.evaluate("document.querySelector('#error').hidden"), "no error shown")
    screenshot(page, "dashboard-job.png")

    say("(4) the sweep's page: two parameter sets of two seeds")
    res = foamd.json(f"/results?sweep={sweep}")
    jobs = {j["id"]: j for j in foamd.json(f"/jobs?sweep={sweep}")["jobs"]}
    by_alpha = {}
    for r in res["rows"]:
        alpha = json.loads(jobs[r["job_id"]]["spec_json"])["cells"]["alpha"]
        value = {x["name"]: x["value"] for x in r["results"]}["contact_angle_deg"]
        by_alpha.setdefault(alpha, []).append(value)
    page.navigate(f"{base}/#/sweep/{sweep}")
    page.wait_for("document.querySelectorAll('table#sweep-sets tr[data-set]').length === 2"
                  " && document.querySelector('canvas#sweep-chart')?.dataset.points")
    sets = page.evaluate(
        "[...document.querySelectorAll('table#sweep-sets tr[data-set]')].map(r => ({key: r.dataset.set,"
        " alpha: r.querySelector('[data-key=\"cells.alpha\"]')?.textContent,"
        " n: r.querySelector('[data-col=n]')?.textContent,"
        " succeeded: r.querySelector('[data-col=succeeded]')?.textContent}))")
    check(sorted(s["alpha"] for s in sets) == ["0.3", "0.6"], f"the sets: {[s['key'] for s in sets]}")
    check(all(s["n"] == "2" and s["succeeded"] == "2" for s in sets), "n = 2 and 2 succeeded in each set")
    check(page.evaluate("document.querySelector('select#sweep-y').value") == "contact_angle_deg",
          "select#sweep-y defaults to contact_angle_deg")
    points = json.loads(page.evaluate("document.querySelector('canvas#sweep-chart').dataset.points"))
    want = [[a, median(v)] for a, v in sorted(by_alpha.items())]
    check(same_points(points, want), f"the sweep chart's medians {points} match /results")
    screenshot(page, "dashboard-sweep.png")

    say("the browser's console:")
    # The 401s of step (1) are expected; anything else is a defect of the page.
    unexpected = [m for m in browser.console if "401" not in m]
    check(not unexpected, "no script errors" + ("" if not unexpected else ": " + "; ".join(unexpected)))


def main() -> int:
    # A SIGTERM (a test runner's timeout) unwinds like a failure: foamd and Chromium are stopped.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    foamd_exe, foam_exe = os.environ.get("FOAMD", ""), os.environ.get("FOAM", "")
    if not (os.access(foamd_exe, os.X_OK) and os.access(foam_exe, os.X_OK)):
        say("FOAMD and FOAM must name the foamd and foam binaries")
        return 2
    if not os.path.exists(cdp.CHROMIUM):
        say(f"skipped: {cdp.CHROMIUM} is missing (apt-get install chromium)")
        return SKIP
    try:
        browser = cdp.Browser()
    except cdp.BrowserUnavailable as e:
        say(f"skipped: Chromium cannot start: {e}")
        return SKIP
    say(f"browser: {browser.version.get('product')}")

    foamd = None
    with tempfile.TemporaryDirectory(prefix="dashboard-test-") as tmp:
        try:
            foamd = Foamd(foamd_exe, foam_exe, Path(tmp))
            run(foamd, browser, Path(tmp))
            say("PASSED")
            return 0
        except (AssertionError, cdp.CDPError, TimeoutError) as e:
            say(f"FAILED: {e}")
            if browser.console:
                say("browser console:\n  " + "\n  ".join(browser.console[-20:]))
            if foamd:
                say("foamd log (tail):\n" + foamd.log_tail())
            return 1
        finally:
            browser.close()
            if foamd:
                foamd.stop()


if __name__ == "__main__":
    sys.exit(main())
