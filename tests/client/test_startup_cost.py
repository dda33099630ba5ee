#!/usr/bin/python3
"""foam's start-up cost, counted rather than timed.

`foam list` under 50 concurrent submits on 2 cores took seconds because every start of foam
spent ~45 ms of CPU, most of it in the dynamic loader: 57 shared libraries, ~15 600 symbol
relocations, ~28 600 relative ones. foam is now linked against static gRPC, protobuf, absl and
OpenSSL, with a static libstdc++ and without PIE (client/CMakeLists.txt). The loader's own
counts (LD_DEBUG=statistics) and the objects it loads say whether that still holds; a time
would depend on the machine's load.

  test_startup_cost.py FOAM STATIC
STATIC: ON when CMake linked foam statically, OFF when it fell back to the shared libraries
(the static archives missing): then the test reports skipped.
"""
import os
import re
import subprocess
import sys

# Generous bounds: the static foam loads 3 objects (libc, libm, the loader) and resolves ~140
# symbols with no relative relocations; the shared one 57, ~15 600 and ~28 600.
MAX_OBJECTS = 5
MAX_RELOCATIONS = 1000
MAX_RELATIVE = 1000


def main():
    foam, static = sys.argv[1], sys.argv[2]
    if static != "ON":
        print("SKIPPED: foam is linked against the shared gRPC (the static archives of "
              "libgrpc++-dev, libprotobuf-dev, libabsl-dev, libssl-dev, libc-ares-dev, "
              "libre2-dev or zlib1g-dev are missing: see CMake's warning)")
        return 77
    env = dict(os.environ, LD_DEBUG="statistics")
    r = subprocess.run([foam, "--version"], env=env, capture_output=True, text=True, timeout=30)
    if r.returncode != 0:
        print(f"foam --version exited {r.returncode}: {r.stdout}{r.stderr}")
        return 1

    def count(what):
        m = re.search(rf"^\s*\d+:\s+{what}:\s+(\d+)\s*$", r.stderr, re.M)
        if not m:
            raise SystemExit(f"no '{what}' in LD_DEBUG=statistics output:\n{r.stderr}")
        return int(m.group(1))

    relocations = count("final number of relocations")
    relative = count("number of relative relocations")
    traced = subprocess.run([foam], env=dict(os.environ, LD_TRACE_LOADED_OBJECTS="1"),
                            capture_output=True, text=True, timeout=30).stdout
    objects = [line.split()[0] for line in traced.splitlines()
               if line.strip() and "linux-vdso" not in line]
    print(f"foam --version: {len(objects)} shared objects ({', '.join(objects)}), "
          f"{relocations} symbol relocations, {relative} relative relocations")
    failed = False
    if len(objects) > MAX_OBJECTS:
        failed = True
        print(f"FAIL: foam loads {len(objects)} shared objects (at most {MAX_OBJECTS}): it is "
              "linked against the shared gRPC/protobuf/absl again, and every start pays the "
              "loader for them (linked shared: 57 objects, ~45 ms of CPU per start)")
    if relocations > MAX_RELOCATIONS:
        failed = True
        print(f"FAIL: {relocations} symbol relocations at start (at most {MAX_RELOCATIONS}): "
              "a shared C++ runtime or gRPC is resolved at every start "
              "(-static-libstdc++, the static archives: client/CMakeLists.txt)")
    if relative > MAX_RELATIVE:
        failed = True
        print(f"FAIL: {relative} relative relocations at start (at most {MAX_RELATIVE}): foam "
              "is linked as a position-independent executable again (-no-pie saves ~4 ms of "
              "CPU per start: docs/benchmarks.md)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
