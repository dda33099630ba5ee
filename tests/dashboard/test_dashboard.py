#!/usr/bin/python3
"""Acceptance test of foamd's browser dashboard, in headless Chromium.

A real foamd (env FOAMD) with a bearer token runs two small jobs and a four-job sweep submitted
by the foam CLI (env FOAM); the test then opens the dashboard foamd serves and checks the
rendered DOM: the token prompt, the job list, a job's chart against its samples, the samples
download, and the sweep page. With SCREENSHOT_DIR set it saves dashboard-jobs.png,
dashboard-job.png and dashboard-sweep.png there (1280x900).

A 2 x 8-cell fusion job (examples/fusion.toml, five snapshots) checks the 3D view last:
the binary mesh route and its token, the three.js scene's triangles against the snapshot's,
drawn pixels of both spheroids' colours read back from the canvas, the slider's first snapshot,
the clip plane, the page without three.js; then a longer fusion job's page while it runs (the
view follows its newest snapshot). With SCREENSHOT_DIR it also saves dashboard-3d.png and
dashboard-3d-clip.png.

Exit status: 0 passed, 1 failed, 2 misconfigured, 77 skipped (no usable /usr/bin/chromium, or
this Chromium cannot create a WebGL context: then every check before the 3D view has passed).
Standard library only; run it as  FOAMD=... FOAM=... /usr/bin/python3 test_dashboard.py
"""

import json
import math
import os
import secrets
import signal
import socket
import struct
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


class Skip(Exception):
    """A check that cannot run here (no WebGL): the test reports skipped, not passed."""


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
    for asset in ("/app.js", "/style.css", "/chart.js", "/view3d.js", "/three.js", "/orbit-controls.js"):
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
    fusion = foamd.foam("submit", str(EXAMPLES / "fusion.toml"), "--tag", "dash-3d",
                        "--set", "snapshot_every_s=150").splitlines()[0].strip()
    say(f"  cell {cell}, doublet {doublet}, sweep {sweep}, fusion {fusion}")
    sweep_jobs = []
    deadline = time.monotonic() + 30
    while len(sweep_jobs) < 4 and time.monotonic() < deadline:
        sweep_jobs = [j["id"] for j in foamd.json(f"/jobs?sweep={sweep}")["jobs"]]
        time.sleep(0.2)
    check(len(sweep_jobs) == 4, f"the sweep has 4 jobs: {sweep_jobs}")
    wait_done(foamd, [cell, doublet, *sweep_jobs, fusion])

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

    view_3d(foamd, browser, fusion)

    say("the browser's console:")
    # The 401s of step (1) are expected; anything else is a defect of the page.
    unexpected = [m for m in browser.console if "401" not in m]
    check(not unexpected, "no script errors" + ("" if not unexpected else ": " + "; ".join(unexpected)))


def mesh_header(body: bytes) -> dict:
    """The JSON header of a .mesh answer (server/mesh_frame.h), its layout checked."""
    check(body[:4] == b"AFM1", f"the mesh starts with AFM1 ({body[:4]!r})")
    (n,) = struct.unpack_from("<I", body, 4)
    h = json.loads(body[8:8 + n])
    check(h["positions_offset"] == 8 + n and h["positions_offset"] % 4 == 0
          and h["triangles_offset"] == h["positions_offset"] + 12 * h["vertices"]
          and len(body) == h["triangles_offset"] + 12 * h["triangles"],
          f"{len(body)} bytes: header, {h['vertices']} float32 vertices, {h['triangles']} uint32 triangles")
    return h


# The canvas read back (it keeps its drawing buffer): pixels unlike the background, of spheroid
# A's blue and B's orange, and a checksum that changes with the picture.
CANVAS_PIXELS = """(async () => {
  const c = document.querySelector('#view3d-canvas');
  const img = new Image();
  img.src = c.toDataURL('image/png');
  await img.decode();
  const cv = document.createElement('canvas');
  cv.width = img.width; cv.height = img.height;
  const g = cv.getContext('2d');
  g.drawImage(img, 0, 0);
  const d = g.getImageData(0, 0, cv.width, cv.height).data;
  let drawn = 0, blue = 0, orange = 0, sum = 0;
  for (let i = 0; i < d.length; i += 4) {
    const r = d[i], gr = d[i + 1], b = d[i + 2];
    if (Math.abs(r - 0xf4) + Math.abs(gr - 0xf6) + Math.abs(b - 0xf9) > 24) drawn++;
    if (b > r + 40 && b > gr + 10) blue++;
    if (r > b + 60 && r > gr + 20) orange++;
    sum = (sum * 31 + r * 7 + gr * 3 + b) % 1000000007;
  }
  return {width: cv.width, height: cv.height, drawn, blue, orange, sum};
})()"""

# The three.js scene as the test sees it: its meshes' triangles, and a sum over their positions.
SCENE = """(() => {
  const v = window.foamdView3D;
  let triangles = 0, meshes = 0, xsum = 0;
  v.scene.traverse(o => {
    if (!o.isMesh) return;
    meshes++;
    const g = o.geometry, p = g.getAttribute('position');
    triangles += (g.index ? g.index.count : p.count) / 3;
    for (let i = 0; i < p.array.length; i += 3) xsum += p.array[i];
  });
  return {triangles, meshes, xsum, clipping: v.material.clippingPlanes.length,
    snapshot: v.canvas.dataset.snapshot, time: document.querySelector('.view3d-time').textContent};
})()"""


def view_3d(foamd: Foamd, browser: cdp.Browser, fusion: str) -> None:
    say("(5) the fusion job's 3D view")
    snaps = foamd.json(f"/jobs/{fusion}/results")["snapshots"]
    check(len(snaps) == 5, f"the fusion job has 5 snapshots: t = {[s['t_s'] for s in snaps]}")
    first, last = snaps[0], snaps[-1]
    path = f"/jobs/{fusion}/snapshots/{first['index']}.mesh"
    status, _, body = foamd.get(path, token=False)
    check(status == 401 and "error" in json.loads(body), f"{path} without the token: {status}")
    status, _, body = foamd.get(path.replace(".mesh", ".vtp"), token=False)
    check(status == 401, f"its .vtp without the token: {status}")
    meshes = {}
    for snap in (first, last):
        status, ctype, body = foamd.get(f"/jobs/{fusion}/snapshots/{snap['index']}.mesh")
        check(status == 200 and ctype == "application/octet-stream", f"snapshot {snap['index']}.mesh: {status} {ctype}")
        h = mesh_header(body)
        check(h["index"] == snap["index"] and h["triangles"] == snap["triangles"]
              and h["vertices"] == snap["vertices"] and h["cells"] == 16 and sorted(set(h["spheroid"])) == [0, 1],
              f"its header: {h['cells']} cells of spheroids 0 and 1, {h['triangles']} triangles as the snapshot list says")
        meshes[snap["index"]] = h

    page = browser.new_page(WIDTH, HEIGHT)
    page.navigate(f"{foamd.base}/#token={foamd.token}")
    page.wait_for("document.querySelectorAll('#jobs tr[data-job-id]').length > 0")
    page.navigate(f"{foamd.base}/#/job/{fusion}")
    state = page.wait_for("['ready', 'unavailable', 'error'].includes(document.querySelector('#view3d-canvas')"
                          "?.dataset.state) && document.querySelector('#view3d-canvas').dataset.state", 30)
    if state == "unavailable":
        raise Skip("no 3D view in this Chromium: "
                   + page.evaluate("document.querySelector('.view3d-message').textContent"))
    check(state == "ready", f"the 3D view loaded a snapshot (state {state})")
    page.wait_for("Number(document.querySelector('#view3d-canvas').dataset.renders) > 0")
    time.sleep(0.3)
    scene = page.evaluate(SCENE)
    check(scene["snapshot"] == str(last["index"]), f"a finished job opens on its latest snapshot ({scene['time']})")
    check(scene["meshes"] == 1 and scene["triangles"] == last["triangles"],
          f"the scene holds {scene['triangles']} triangles, the snapshot {last['triangles']}")
    px = page.evaluate(CANVAS_PIXELS)
    total = px["width"] * px["height"]
    check(px["drawn"] > 0.03 * total, f"{px['drawn']} of {total} canvas pixels are drawn (not background)")
    check(px["blue"] > 0.005 * total and px["orange"] > 0.005 * total,
          f"both spheroids' colours show: {px['blue']} blue, {px['orange']} orange pixels")
    check(page.evaluate("document.querySelector('.view3d-legend').textContent").count("spheroid") == 2,
          "the legend names spheroids A and B")
    screenshot(page, "dashboard-3d.png")

    say("    the slider to the first snapshot")
    page.evaluate("(() => { const s = document.querySelector('.view3d-slider'); s.value = 0;"
                  " s.dispatchEvent(new Event('input')); })()")
    page.wait_for(f"document.querySelector('#view3d-canvas').dataset.snapshot === {js(str(first['index']))}"
                  " && document.querySelector('#view3d-canvas').dataset.state === 'ready'")
    time.sleep(0.3)
    scene0 = page.evaluate(SCENE)
    check(scene0["triangles"] == first["triangles"], f"the scene holds snapshot {first['index']}'s {first['triangles']} triangles")
    check(scene0["xsum"] != scene["xsum"], "its vertices are the first snapshot's, not the last's")
    check(scene0["time"].startswith("t = 0 s") and "snapshot 1 of 5" in scene0["time"], f"the label: {scene0['time']}")
    px0 = page.evaluate(CANVAS_PIXELS)
    check(px0["sum"] != px["sum"] and px0["drawn"] > 0.03 * total, "the picture changed")

    say("    the clip plane through the fusion axis")
    page.evaluate("document.querySelector('.view3d-clip').click()")
    page.wait_for("window.foamdView3D.material.clippingPlanes.length === 1")
    time.sleep(0.3)
    pxc = page.evaluate(CANVAS_PIXELS)
    check(pxc["sum"] != px0["sum"] and pxc["drawn"] > 0.03 * total, "the clipped picture differs and is drawn")
    screenshot(page, "dashboard-3d-clip.png")
    page.evaluate("document.querySelector('.view3d-clip').click()")

    say("    colour by cell id")
    page.evaluate("(() => { const s = document.querySelector('.view3d-color'); s.value = 'cell';"
                  " s.dispatchEvent(new Event('change')); })()")
    page.wait_for("document.querySelector('.view3d-legend').textContent.includes('16 cells')")
    time.sleep(0.3)
    check(page.evaluate(CANVAS_PIXELS)["sum"] not in (px0["sum"], pxc["sum"]), "recoloured by cell id")
    check(page.evaluate("document.querySelector('#error').hidden"), "no error shown")
    # Leaving the page gives the WebGL context back (the console check at the end sees errors).
    page.evaluate("location.hash = '#/'")
    page.wait_for("document.querySelectorAll('#jobs tr[data-job-id]').length > 0")
    check(page.evaluate("window.foamdView3D.renderer") is None, "leaving the job page disposes of the view")
    page.close()

    say("    three.js failing to load: the page says so and keeps its charts")
    page = browser.new_page(WIDTH, HEIGHT)
    page.send("Network.enable")
    # Both: Debian's OrbitControls.js throws on load without three.js before it.
    page.send("Network.setBlockedURLs", {"urls": ["*/three.js", "*/orbit-controls.js"]})
    page.navigate(f"{foamd.base}/#token={foamd.token}")
    page.navigate(f"{foamd.base}/#/job/{fusion}")
    page.wait_for("document.querySelector('canvas#main-chart')?.dataset.points")
    check(page.evaluate("document.querySelector('#view3d-canvas').dataset.state") == "unavailable"
          and page.evaluate("document.querySelector('.view3d-message').textContent")
          == "No 3D view: three.js did not load.", "the 3D view says three.js did not load")
    check(len(json.loads(page.evaluate("document.querySelector('canvas#main-chart').dataset.points"))) > 10,
          "the θ(t) chart is drawn all the same")
    page.close()
    # The blocked requests are the console errors this step causes.
    browser.console[:] = [m for m in browser.console if "ERR_BLOCKED_BY_CLIENT" not in m]

    say("(6) a running fusion job: the 3D view follows its newest snapshot")
    # Three times as long as the first (its spheroids are cached now): a snapshot every 100
    # simulated seconds gives the page several to follow while the job runs.
    running = foamd.foam("submit", str(EXAMPLES / "fusion.toml"), "--tag", "dash-follow",
                         "--set", "duration_s=1800", "--set", "snapshot_every_s=100").splitlines()[0].strip()
    deadline = time.monotonic() + 120
    while True:
        res = foamd.json(f"/jobs/{running}/results")
        if res.get("snapshots") and not res["job"].get("terminal"):
            break
        if res["job"].get("terminal") or time.monotonic() > deadline:
            raise AssertionError(f"job {running} never ran with a snapshot: {res['job'].get('state')}")
        time.sleep(0.2)
    page = browser.new_page(WIDTH, HEIGHT)
    page.navigate(f"{foamd.base}/#token={foamd.token}")
    page.navigate(f"{foamd.base}/#/job/{running}")
    shown = set()
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        state, snapshot, ready = page.evaluate(
            "[document.querySelector('#job-state')?.textContent, document.querySelector('#view3d-canvas')?.dataset.snapshot,"
            " document.querySelector('#view3d-canvas')?.dataset.state]")
        if state in TERMINAL:
            break
        if state == "running" and ready == "ready":
            shown.add(int(snapshot))
        time.sleep(0.5)
    wait_done(foamd, [running])
    last = foamd.json(f"/jobs/{running}/results")["snapshots"][-1]
    check(len(shown) >= 2, f"while the job ran the view followed it through snapshots {sorted(shown)}")
    page.wait_for(f"document.querySelector('#view3d-canvas').dataset.snapshot === {js(str(last['index']))}"
                  " && document.querySelector('#view3d-canvas').dataset.state === 'ready'", 30)
    label = page.evaluate("document.querySelector('.view3d-time').textContent")
    check(label.endswith("(latest)") and f"snapshot {len(foamd.json(f'/jobs/{running}/results')['snapshots'])} of" in label,
          f"it ends on the last one: {label}")
    page.close()


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
        # WebGL on the CPU (SwiftShader), which newer Chromiums offer only when asked.
        browser = cdp.Browser(extra_args=("--enable-unsafe-swiftshader",))
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
        except Skip as e:
            say(f"SKIPPED: {e}")
            return SKIP
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
