#!/usr/bin/env python3
"""Cost of one spec under several numerics, on a many-core host, over a common simulated window.

Every (configuration, seed) runs at once, one thread each, pinned to its own core, so the host's
drift falls on all alike. Each run goes until DURATION simulated seconds or DEADLINE wall
seconds, whichever comes first. The runs are compared over the simulated window [0, T] that all
of them reached (T: the smallest last sample time): the cost is samples.csv's wall_s at T less
its wall_s at t = 0 (the spheroids' loading or preparation; one pinned thread, so wall ≈ CPU;
the rusage CPU of the whole run is kept beside it as a check).
A configuration whose settings begin with --foam-run=PATH runs that binary (an older engine
built in a worktree, say) instead of FOAM_RUN.

  bench/step_cost_window.py FOAM_RUN SPEC CACHE OUT --seeds 1,2,3,4 --duration 1800 \
      --deadline 420 'NAME|--set K=V ...' ...

Writes OUT/rows.csv (name, seed, t_window_s, wall_at_window_s, steps_at_window, t_last_s,
wall_last_s, cpu_rusage_s, exit) and OUT/curves.csv (name, seed, t_s, wall_s, steps), and prints
per configuration the median cost per simulated hour over the window and its ratio to the first.
Only the configurations' own seeds are paired: the ratio per seed is the first configuration's
cost over this one's, and its median and range are printed.
"""
import argparse
import csv
import os
import shlex
import signal
import statistics
import subprocess
import sys
import time


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("foam_run")
    ap.add_argument("spec")
    ap.add_argument("cache")
    ap.add_argument("out")
    ap.add_argument("configs", nargs="+", help="'NAME|--set K=V ...'")
    ap.add_argument("--seeds", default="1,2,3,4")
    ap.add_argument("--duration", type=float, default=1800.0, help="simulated seconds")
    ap.add_argument("--deadline", type=float, default=420.0, help="wall seconds")
    a = ap.parse_args()

    seeds = [int(s) for s in a.seeds.split(",")]
    cfgs = []
    for c in a.configs:
        name, _, sets = c.partition("|")
        words = shlex.split(sets)
        exe = a.foam_run
        if words and words[0].startswith("--foam-run="):
            exe = words.pop(0).split("=", 1)[1]
        cfgs.append((name, exe, words))
    runs = [(n, exe, s, sets) for n, exe, sets in cfgs for s in seeds]
    try:
        cores = sorted(os.sched_getaffinity(0))
    except AttributeError:
        cores = list(range(os.cpu_count() or 1))
    if len(runs) > len(cores):
        sys.exit(f"{len(runs)} runs need as many cores; this host offers {len(cores)}")
    os.makedirs(a.out, exist_ok=True)

    procs = {}
    for i, (name, exe, seed, sets) in enumerate(runs):
        d = os.path.join(a.out, f"{''.join(ch if ch.isalnum() or ch == '.' else '_' for ch in name)}-s{seed}")
        cmd = [exe, a.spec, "--out", d, "--force", "--spheroid-cache", a.cache,
               "--threads", "1", "-q", "--checkpoint-every", "0",
               "--set", f"duration_s={a.duration}", "--set", "snapshot_every_s=0",
               "--set", f"seed={seed}"] + sets
        core = cores[i]
        env = dict(os.environ, OMP_NUM_THREADS="1")
        p = subprocess.Popen(cmd, env=env, preexec_fn=lambda c=core: os.sched_setaffinity(0, {c}))
        procs[p.pid] = (p, name, seed, d)
    t0 = time.monotonic()
    done = {}
    stopped_at = None
    while len(done) < len(procs):
        pid, status, ru = os.wait4(-1, os.WNOHANG)
        if pid in procs:
            done[pid] = (os.waitstatus_to_exitcode(status), ru.ru_utime + ru.ru_stime)
            continue
        elapsed = time.monotonic() - t0
        if stopped_at is None and elapsed > a.deadline:
            stopped_at = elapsed
            for q, (p, *_rest) in procs.items():
                if q not in done:
                    p.send_signal(signal.SIGINT)  # foam-run stops after its current step
        if stopped_at is not None and elapsed > stopped_at + 30:
            for q, (p, *_rest) in procs.items():
                if q not in done:
                    p.kill()
        time.sleep(0.2)

    def samples(d):
        with open(os.path.join(d, "samples.csv")) as f:
            rows = [(float(r["t_s"]), float(r["wall_s"]), int(float(r["steps"])))
                    for r in csv.DictReader(f)]
        w0 = rows[0][1] if rows and rows[0][0] == 0 else 0.0
        return [(t, w - w0, st) for t, w, st in rows]

    curves = {}
    for pid, (p, name, seed, d) in procs.items():
        curves[(name, seed)] = samples(d)
    t_window = min(c[-1][0] for c in curves.values() if c)
    rows = []
    with open(os.path.join(a.out, "curves.csv"), "w") as f:
        f.write("name,seed,t_s,wall_s,steps\n")
        for (name, seed), c in curves.items():
            for t, w, st in c:
                f.write(f"{name},{seed},{t:g},{w:.3f},{st}\n")
    for pid, (p, name, seed, d) in procs.items():
        c = curves[(name, seed)]
        at = [x for x in c if x[0] <= t_window + 1e-9][-1]
        code, cpu = done[pid]
        rows.append(dict(name=name, seed=seed, t_window_s=t_window, wall_at_window_s=at[1],
                         steps_at_window=at[2], t_last_s=c[-1][0], wall_last_s=c[-1][1],
                         cpu_rusage_s=round(cpu, 2), exit=code))
    with open(os.path.join(a.out, "rows.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)

    print(f"window: the first {t_window:g} simulated s (all {len(runs)} runs reached it)")
    base = {r["seed"]: r["wall_at_window_s"] for r in rows if r["name"] == cfgs[0][0]}
    print(f"{'configuration':<22} {'CPU s/sim. h (median, range)':>30} {'steps':>7}"
          f" {'ratio (median, range over seeds)':>34}")
    for name, _, _ in cfgs:
        mine = [r for r in rows if r["name"] == name]
        per_h = [r["wall_at_window_s"] / t_window * 3600 for r in mine]
        ratios = [base[r["seed"]] / r["wall_at_window_s"] for r in mine]
        steps = statistics.median(r["steps_at_window"] for r in mine)
        print(f"{name:<22} {statistics.median(per_h):>10.0f} ({min(per_h):.0f}–{max(per_h):.0f})"
              f"{'':>8} {steps:>7.0f} {statistics.median(ratios):>12.2f}"
              f" ({min(ratios):.2f}–{max(ratios):.2f})")


if __name__ == "__main__":
    main()
