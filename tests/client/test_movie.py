#!/usr/bin/python3
"""Acceptance test of `foam export --movie`: a real foamd (env FOAMD) runs a 2 x 8-cell
fusion job with five snapshots and a cell job without any; foam (env FOAM) renders the first to
an MP4 and a GIF with Debian's ffmpeg, and ffprobe counts their frames. Also: the first frame
shows both spheroids' colours; no snapshots, no ffmpeg, a bad file name: exit 2 with a message
saying why; an unknown job: exit 5; a movie ffmpeg leaves incomplete (exit 0, no trailer) never
replaces the older one. With SCREENSHOT_DIR set it saves the movie's last frame there
as movie-frame.png.

Exit status: 0 passed, 1 failed, 2 misconfigured, 77 skipped (no ffmpeg/ffprobe on PATH).
Standard library only; run it as  FOAMD=... FOAM=... /usr/bin/python3 test_movie.py
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

sys.dont_write_bytecode = True
# The dashboard test's foamd fixture: a real foamd with a token on free loopback ports.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "dashboard"))
from test_dashboard import EXAMPLES, Foamd, check, say, wait_done  # noqa: E402

SKIP = 77


def foam(foamd: Foamd, *args: str, env=None) -> subprocess.CompletedProcess:
    cmd = [foamd.foam_exe, "--server", foamd.address, "--token-file", str(foamd.token_file), *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)


def probe(path: Path) -> dict:
    r = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0",
                        "-show_entries", "stream=codec_name,width,height,nb_read_frames",
                        "-of", "json", str(path)], capture_output=True, text=True)
    check(r.returncode == 0, f"ffprobe reads {path.name}" + (f": {r.stderr}" if r.returncode else ""))
    return json.loads(r.stdout)["streams"][0]


def frame_rgb(path: Path, which: str, width: int, height: int) -> bytes:
    """The first or the last frame of a movie as raw RGB."""
    vf = "select=eq(n\\,0)" if which == "first" else "reverse"
    r = subprocess.run(["ffmpeg", "-v", "error", "-i", str(path), "-vf", vf, "-frames:v", "1",
                        "-f", "rawvideo", "-pix_fmt", "rgb24", "-"], capture_output=True)
    check(r.returncode == 0 and len(r.stdout) == 3 * width * height,
          f"the {which} frame decodes to {width}x{height} RGB ({len(r.stdout)} bytes)")
    return r.stdout


def colours(rgb: bytes) -> tuple:
    """(blue, orange) pixel counts: spheroid A's and B's colours under any shade."""
    blue = orange = 0
    for i in range(0, len(rgb), 3):
        r, g, b = rgb[i], rgb[i + 1], rgb[i + 2]
        if b > r + 40 and b > g + 10:
            blue += 1
        elif r > b + 60 and r > g + 20:
            orange += 1
    return blue, orange


def run(foamd: Foamd, tmp: Path) -> None:
    fusion = foamd.foam("submit", str(EXAMPLES / "fusion.toml"), "--tag", "movie",
                        "--set", "snapshot_every_s=150").splitlines()[0].strip()
    bare = foamd.foam("submit", str(EXAMPLES / "cell.toml"), "--set", "duration_s=10",
                      "--set", "snapshot_every_s=0").splitlines()[0].strip()
    wait_done(foamd, [fusion, bare])
    snaps = foamd.json(f"/jobs/{fusion}/results")["snapshots"]
    check(len(snaps) == 5, f"the fusion job has {len(snaps)} snapshots")

    say("MP4")
    mp4 = tmp / "fusion.mp4"
    r = foam(foamd, "export", "--movie", fusion, str(mp4))
    check(r.returncode == 0 and r.stdout.strip() == str(mp4),
          f"foam export --movie {fusion} fusion.mp4 exits 0 and prints the path ({r.returncode}: {r.stderr.strip()})")
    s = probe(mp4)
    check(s["codec_name"] == "h264" and (s["width"], s["height"]) == (1280, 720), f"h264, 1280x720: {s}")
    check(int(s["nb_read_frames"]) == len(snaps), f"{s['nb_read_frames']} frames, one a snapshot")
    blue, orange = colours(frame_rgb(mp4, "first", 1280, 720))
    check(blue > 2000 and orange > 2000, f"the first frame shows both spheroids: {blue} blue, {orange} orange pixels")
    out = os.environ.get("SCREENSHOT_DIR")
    if out:
        os.makedirs(out, exist_ok=True)
        subprocess.run(["ffmpeg", "-v", "error", "-y", "-i", str(mp4), "-vf", "reverse", "-frames:v", "1",
                        os.path.join(out, "movie-frame.png")], check=True)
        say(f"  --  {os.path.join(out, 'movie-frame.png')}")

    say("GIF, coloured by pressure")
    gif = tmp / "fusion.gif"
    r = foam(foamd, "export", "--movie", fusion, str(gif), "--size", "320x180", "--color", "pressure", "--fps", "2")
    check(r.returncode == 0, f"foam export --movie ... fusion.gif exits 0 ({r.stderr.strip()})")
    s = probe(gif)
    check(s["codec_name"] == "gif" and (s["width"], s["height"]) == (320, 180), f"gif, 320x180: {s}")
    check(int(s["nb_read_frames"]) == len(snaps), f"{s['nb_read_frames']} frames, one a snapshot")

    say("refusals")
    none = tmp / "none.mp4"
    r = foam(foamd, "export", "--movie", bare, str(none))
    check(r.returncode == 2 and "no snapshots" in r.stderr and not none.exists(),
          f"a job without snapshots: exit {r.returncode}, {r.stderr.strip()!r}, no file")
    r = foam(foamd, "export", "--movie", fusion, str(tmp / "x.mp4"), env=dict(os.environ, PATH="/nonexistent"))
    check(r.returncode == 2 and "apt-get install ffmpeg" in r.stderr and not (tmp / "x.mp4").exists(),
          f"no ffmpeg on PATH: exit {r.returncode}, {r.stderr.strip()!r}")
    say("an incomplete movie never replaces a good one")
    # ffmpeg on a full disk prints "Error writing trailer" yet exits 0: a stand-in that does the
    # same (writes a file that is no movie, exits 0) must not replace the movie made above, nor
    # touch a file of the user's named like a temporary.
    fake = tmp / "fakebin"
    fake.mkdir()
    (fake / "ffmpeg").write_text('#!/bin/sh\nfor last; do :; done\ncat > /dev/null\n'
                                 'printf "no moov atom" > "$last"\nexit 0\n')
    (fake / "ffmpeg").chmod(0o755)
    good = mp4.read_bytes()
    users = tmp / "fusion.mp4.part"
    users.write_text("mine")
    r = foam(foamd, "export", "--movie", fusion, str(mp4),
             env=dict(os.environ, PATH=f"{fake}:{os.environ.get('PATH', '/usr/bin')}"))
    left = sorted(p.name for p in tmp.iterdir() if p.name.startswith("fusion.mp4."))
    check(r.returncode != 0 and "incomplete" in r.stderr and mp4.read_bytes() == good
          and users.read_text() == "mine" and left == ["fusion.mp4.part"],
          f"a movie ffmpeg left without its trailer: exit {r.returncode}, {r.stderr.strip()!r}, "
          f"the older movie kept, the user's file untouched, nothing else left ({left})")
    r = foam(foamd, "export", "--movie", fusion, str(tmp / "x.avi"))
    check(r.returncode == 2 and ".mp4 or .gif" in r.stderr, f"fusion.avi: exit {r.returncode}, {r.stderr.strip()!r}")
    r = foam(foamd, "export", "--movie", "j-000000000000", str(tmp / "x.mp4"))
    check(r.returncode == 5, f"an unknown job: exit {r.returncode}, {r.stderr.strip()!r}")


def main() -> int:
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    foamd_exe, foam_exe = os.environ.get("FOAMD", ""), os.environ.get("FOAM", "")
    if not (os.access(foamd_exe, os.X_OK) and os.access(foam_exe, os.X_OK)):
        say("FOAMD and FOAM must name the foamd and foam binaries")
        return 2
    if not (shutil.which("ffmpeg") and shutil.which("ffprobe")):
        say("SKIPPED: ffmpeg/ffprobe are not on PATH (apt-get install ffmpeg)")
        return SKIP
    foamd = None
    with tempfile.TemporaryDirectory(prefix="movie-test-") as tmp:
        try:
            foamd = Foamd(foamd_exe, foam_exe, Path(tmp))
            run(foamd, Path(tmp))
            say("PASSED")
            return 0
        except (AssertionError, TimeoutError, subprocess.SubprocessError) as e:
            say(f"FAILED: {e}")
            if foamd:
                say("foamd log (tail):\n" + foamd.log_tail())
            return 1
        finally:
            if foamd:
                foamd.stop()


if __name__ == "__main__":
    sys.exit(main())
