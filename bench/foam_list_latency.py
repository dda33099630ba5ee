#!/usr/bin/python3
"""Where `foam list` spends its time under 50 concurrent submits.

Starts its own foamd (a temporary database, a free loopback port, no engine workers: submits
stay queued), keeps 50 `foam submit` processes running in a loop, and times, N times each:
  start   `foam --help`: process start and dynamic linking, no channel, no RPC
  list-ip `foam list --server 127.0.0.1:P`
  list-lh `foam list --server localhost:P` (name resolution added)
  rpc     ListJobs on a channel that is already connected (Python grpc: the server's share)
Prints p50 / p90 / p99 / max in ms of each.

  bench/foam_list_latency.py [BUILD_DIR (build/release)] [N (60)] [SUBMITTERS (50)]
"""
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def pct(xs, q):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))]


def main():
    build = sys.argv[1] if len(sys.argv) > 1 else "build/release"
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 60
    submitters = int(sys.argv[3]) if len(sys.argv) > 3 else 50
    foamd = os.path.join(build, "server", "foamd")
    foam = os.path.join(build, "client", "foam")
    tmp = tempfile.mkdtemp(prefix="foam-list-latency-")
    port = free_port()
    spec = os.path.join(tmp, "cell.toml")
    with open(spec, "w") as f:
        f.write('scene = "cell"\nduration_s = 5\n')
    env = dict(os.environ, FOAM_SERVER=f"127.0.0.1:{port}")
    server = subprocess.Popen(
        [foamd, "--db", os.path.join(tmp, "f.db"), "--listen", f"127.0.0.1:{port}",
         "--workers", "1", "--log-level", "warn"],
        stdout=subprocess.DEVNULL, stderr=open(os.path.join(tmp, "foamd.log"), "w"))
    # --workers 1 runs the queue's 5 s cells: a loaded server.
    try:
        for _ in range(100):
            if subprocess.run([foam, "list", "--limit", "1"], env=env, capture_output=True).returncode == 0:
                break
            time.sleep(0.1)
        stop = threading.Event()

        def submit_loop():
            while not stop.is_set():
                subprocess.run([foam, "submit", spec], env=env, capture_output=True)

        threads = [threading.Thread(target=submit_loop) for _ in range(submitters)]
        for t in threads:
            t.start()
        time.sleep(2)

        def timed(cmd, e=env):
            t0 = time.perf_counter()
            r = subprocess.run(cmd, env=e, capture_output=True)
            dt = (time.perf_counter() - t0) * 1000
            if r.returncode != 0:
                raise RuntimeError(f"{cmd}: {r.stderr.decode()}")
            return dt

        results = {"start": [], "list-ip": [], "list-lh": [], "rpc": []}
        import grpc
        ch = grpc.insecure_channel(f"127.0.0.1:{port}")
        grpc.channel_ready_future(ch).result(timeout=10)
        # ListJobsRequest{page_size: 50} by hand (field 6, varint): no generated modules needed.
        list_jobs = ch.unary_unary("/activefoam.v1.Foam/ListJobs")

        def rpc():
            t0 = time.perf_counter()
            list_jobs(b"\x30\x32", timeout=30)
            return (time.perf_counter() - t0) * 1000

        lh_env = dict(env, FOAM_SERVER=f"localhost:{port}")
        for _ in range(n):
            results["start"].append(timed([foam, "--help"]))
            results["list-ip"].append(timed([foam, "list", "--limit", "50"]))
            results["list-lh"].append(timed([foam, "list", "--limit", "50"], lh_env))
            results["rpc"].append(rpc())
        stop.set()
        for t in threads:
            t.join()
        print(f"{n} tries each, {submitters} concurrent submitters, {os.cpu_count()} CPUs")
        print(f"{'':8} {'p50':>7} {'p90':>7} {'p99':>7} {'max':>7}  (ms)")
        for k, xs in results.items():
            if xs:
                print(f"{k:8} {pct(xs, .5):7.0f} {pct(xs, .9):7.0f} {pct(xs, .99):7.0f} {max(xs):7.0f}")
    finally:
        server.terminate()
        server.wait()
        subprocess.run(["rm", "-rf", tmp])


if __name__ == "__main__":
    main()
