#!/usr/bin/python3
"""Times foamd's snapshot routes over loopback: the 3D view's binary .mesh and the .vtp, each
fetched REPEATS times (a fresh connection each, as foamd serves one request a connection);
prints bytes and the median, min and max wall time. With --browser also what the dashboard
pays: fetch + parse of the .mesh inside headless Chromium (View3D.parseMesh), and the time
from the slider's move to the 3D view showing that snapshot (fetch, parse, geometry, normals,
colours; the render that follows is one frame).

    bench/mesh_route.py http://127.0.0.1:8080 JOB_ID --token-file F [--index N] [--repeats 15]
                        [--browser]

Standard library only (and tests/dashboard/cdp.py for --browser).
"""

import argparse
import json
import statistics
import sys
import time
import urllib.request
from pathlib import Path


def fetch(url: str, token: str):
    req = urllib.request.Request(url)
    if token:
        req.add_header("Authorization", f"Bearer {token}")
    t0 = time.perf_counter()
    with urllib.request.urlopen(req, timeout=60) as r:
        body = r.read()
    return time.perf_counter() - t0, body


def summary(name: str, times, size: int) -> None:
    ms = [1000 * t for t in times]
    print(f"{name:<28} {size:>10} bytes  median {statistics.median(ms):8.1f} ms"
          f"  min {min(ms):8.1f}  max {max(ms):8.1f}  ({len(ms)} fetches)")


def browser_times(base: str, job: str, token: str, index: int, repeats: int) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "dashboard"))
    import cdp

    b = cdp.Browser(extra_args=("--enable-unsafe-swiftshader",))
    try:
        page = b.new_page(1280, 900)
        page.navigate(f"{base}/#token={token}")
        page.navigate(f"{base}/#/job/{job}")
        page.wait_for("['ready', 'unavailable'].includes(document.querySelector('#view3d-canvas')?.dataset.state)", 60)
        ms = page.evaluate(f"""(async () => {{
          const out = [];
          for (let k = 0; k < {repeats}; k++) {{
            const t0 = performance.now();
            const res = await fetch('jobs/{job}/snapshots/{index}.mesh', {{headers: {{Authorization: 'Bearer {token}'}}, cache: 'no-store'}});
            const mesh = View3D.parseMesh(await res.arrayBuffer());
            if (!mesh.triangles.length) throw new Error('empty');
            out.push(performance.now() - t0);
          }}
          return out;
        }})()""", timeout_s=300)
        print(f"{'browser: fetch + parse':<28} {'':>10}        median {statistics.median(ms):8.1f} ms"
              f"  min {min(ms):8.1f}  max {max(ms):8.1f}  ({len(ms)} fetches)")
        if page.evaluate("document.querySelector('#view3d-canvas').dataset.state") != "ready":
            print("browser: no 3D view here (no WebGL): slider timing skipped")
            return
        # Slider to snapshot k: fetched (not cached: a fresh page each time), parsed, shown.
        shown = []
        snaps = page.evaluate("window.foamdView3D.snaps.map(s => s.index)")
        k = snaps.index(index)
        for _ in range(min(repeats, 5)):
            page.evaluate("location.reload()")
            time.sleep(0.5)
            page.wait_for("document.readyState === 'complete'"
                          " && document.querySelector('#view3d-canvas')?.dataset.state === 'ready'", 60)
            if k == len(snaps) - 1:  # the page opened on it: move away and back is cached; go to 0
                k = 0
            t = page.evaluate(f"""(async () => {{
              const c = document.querySelector('#view3d-canvas'), s = document.querySelector('.view3d-slider');
              const t0 = performance.now();
              s.value = {k}; s.dispatchEvent(new Event('input'));
              while (!(c.dataset.snapshot === String(window.foamdView3D.snaps[{k}].index) && c.dataset.state === 'ready'))
                await new Promise(r => setTimeout(r, 2));
              return performance.now() - t0;
            }})()""", timeout_s=120)
            shown.append(t)
        print(f"{'browser: slider to shown':<28} {'':>10}        median {statistics.median(shown):8.1f} ms"
              f"  min {min(shown):8.1f}  max {max(shown):8.1f}  ({len(shown)} page loads; snapshot {snaps[k]})")
    finally:
        b.close()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("base", help="foamd's --http URL, e.g. http://127.0.0.1:8080")
    ap.add_argument("job")
    ap.add_argument("--token-file", default="")
    ap.add_argument("--index", type=int, default=-1, help="snapshot index (default: the latest)")
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--browser", action="store_true")
    a = ap.parse_args()
    token = Path(a.token_file).read_text().strip() if a.token_file else ""
    base = a.base.rstrip("/")
    results = json.loads(fetch(f"{base}/jobs/{a.job}/results", token)[1])
    snaps = results.get("snapshots", [])
    if not snaps:
        print("the job has no snapshots")
        return 2
    info = snaps[-1] if a.index < 0 else next(s for s in snaps if s["index"] == a.index)
    print(f"job {a.job} snapshot {info['index']}: t = {info['t_s']} s, {info['vertices']} vertices, "
          f"{info['triangles']} triangles")
    for ext in ("mesh", "vtp"):
        times, size = [], 0
        for _ in range(a.repeats):
            t, body = fetch(f"{base}/jobs/{a.job}/snapshots/{info['index']}.{ext}", token)
            times.append(t)
            size = len(body)
        summary(f"GET .../{info['index']}.{ext}", times, size)
    if a.browser:
        browser_times(base, a.job, token, info["index"], a.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
