#!/usr/bin/python3
"""The adversarial corpus: hostile and mistaken input, as data, through one runner.

Every case file in this directory (*.toml, `[[case]]` tables) names an input, the program or
call that receives it and the answer it must get: an exit status or a gRPC status code, and
the words of the error that name the field, key, flag or file at fault. The runner starts one
foamd on free loopback ports (gRPC and HTTP) with a temporary database and drives each case
through what the case names:

  foamd.toml     foamd's own command line and --config files (a process per case)
  listeners.toml foamd beside the running one on its ports (IPv4, IPv6, HTTP)
  tokens.toml    token contents: foamd --token-file, foam --token-file, FOAM_TOKEN and the
                 Python client's token=
  specs.toml     spec texts (JSON/TOML) and --set values: foam-run, foam submit and SubmitJob
  rpc.toml       raw gRPC requests at and beyond each field's limit (the generated stubs)
  http.toml      raw HTTP requests on a socket, and a small flood of idle and slow clients
  python.toml    the Python client's arguments and environment (a process per case), and
                 the study tool's command line (python3 -m activefoam.study, a process per case)

and at the end requires the server to be healthy (gRPC health, /healthz), a normal submit and
list to work, and the number of stored jobs to be exactly what the accepted cases stored:
nothing refused was stored.

Values may be written as expansions, for what does not fit in a file: {repeat = "x", times = N}
(a string), {parts = [["[", 1000], ["]", 1000]]} (a concatenation), {hex = "00ff"} (bytes),
{items = V, times = N} (a list of N copies). A case with `xfail = "why"` is a known defect:
it is reported, and fails the run only if it passes (then the note is stale).

  run_corpus.py BUILD_DIR [CASE_FILE_OR_NAME_FILTER...]
Exit 0: every case held; 1: a case failed; 77: something needed is missing (SKIPPED).
"""
import base64
import json
import os
import re
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PROC_TIMEOUT_S = 10  # a process that should have refused at once but serves instead


def skip(why):
    print(f"SKIPPED: {why}")
    sys.exit(77)


try:
    import tomllib
except ImportError:
    skip("Python 3.11's tomllib is missing")

if len(sys.argv) < 2:
    sys.exit(__doc__)
BUILD = Path(sys.argv[1]).resolve()
FILTERS = sys.argv[2:]
FOAMD = BUILD / "server" / "foamd"
FOAM = BUILD / "client" / "foam"
FOAM_RUN = BUILD / "runner" / "foam-run"
for exe in (FOAMD, FOAM, FOAM_RUN):
    if not exe.exists():
        skip(f"{exe} is not built")
sys.path.insert(0, str(BUILD / "python"))
try:
    import grpc
    from google.protobuf import json_format
    from activefoam.v1 import service_pb2, service_pb2_grpc
except ImportError as e:
    skip(f"{e.name} cannot be imported (python3-grpcio, python3-protobuf, the generated stubs "
         f"under {BUILD / 'python'})")
try:
    import activefoam  # the Python client (pandas): its token checks
except ImportError as e:
    activefoam = None
    PY_CLIENT_MISSING = str(e)


def limit_memory():
    """In a Python case's process: a 4 GiB address space. A regression that reads /dev/zero to
    its end fails its case, not the machine."""
    import resource
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))


def free_port(family=socket.AF_INET, host="127.0.0.1"):
    with socket.socket(family) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def has_ipv6_loopback():
    try:
        free_port(socket.AF_INET6, "::1")
        return True
    except OSError:
        return False


def expand(v):
    """The expansions of the case files (module docstring)."""
    if isinstance(v, dict):
        if "repeat" in v:
            return v["repeat"] * v["times"]
        if "parts" in v:
            return "".join(s * n for s, n in v["parts"])
        if "hex" in v:
            return bytes.fromhex(v["hex"])
        if "b64" in v:
            return base64.b64decode(v["b64"])
        if "items" in v:
            return [expand(v["items"]) for _ in range(v["times"])]
        return {k: expand(x) for k, x in v.items()}
    if isinstance(v, list):
        return [expand(x) for x in v]
    return v


def to_bytes(v):
    v = expand(v)
    return v if isinstance(v, bytes) else v.encode()


def short(s, n=400):
    s = s if isinstance(s, str) else repr(s)
    return s if len(s) <= n else s[:n] + f"... ({len(s)} chars)"


class Runner:
    def __init__(self):
        self.tmp = Path(tempfile.mkdtemp(prefix="foam-adversarial-"))
        self.port = free_port()
        self.http_port = free_port()
        self.ipv6 = has_ipv6_loopback()
        self.passed, self.failed, self.xfailed, self.skipped = [], [], [], []
        self.stored = 0  # jobs the accepted cases stored
        self.log = self.tmp / "foamd.log"
        self.server = subprocess.Popen(
            [str(FOAMD), "--listen", f"127.0.0.1:{self.port}", "--http",
             f"127.0.0.1:{self.http_port}", "--db", str(self.tmp / "foamd.db"), "--workers", "1",
             "--log-level", "warn"],
            stdout=self.log.open("w"), stderr=subprocess.STDOUT)
        self.channel = grpc.insecure_channel(f"127.0.0.1:{self.port}")
        try:
            grpc.channel_ready_future(self.channel).result(timeout=20)
        except grpc.FutureTimeoutError:
            self.server.kill()
            sys.exit("foamd did not start:\n" + self.log.read_text())
        self.stub = service_pb2_grpc.FoamStub(self.channel)
        self.env = dict(os.environ, FOAM_SERVER=f"127.0.0.1:{self.port}")
        for k in ("FOAM_TOKEN", "FOAM_TLS_CA"):
            self.env.pop(k, None)

    # -- bookkeeping -----------------------------------------------------------------------
    def outcome(self, case, problems, what=""):
        name = f"{case['_file']}: {case['name']}{' [' + what + ']' if what else ''}"
        xfail = case.get("xfail")
        if problems and xfail:
            self.xfailed.append(name)
            print(f"XFAIL {name}: {xfail}")
        elif problems:
            self.failed.append(name)
            print(f"FAIL  {name}")
            for p in problems:
                print(f"      {p}")
        elif xfail:
            self.failed.append(name)
            print(f"FAIL  {name}: passes, but is marked xfail ({xfail}): remove the mark")
        else:
            self.passed.append(name)

    def placeholders(self, s, extra=None):
        values = {"dir": str(self.tmp), "grpc_port": str(self.port),
                  "http_port": str(self.http_port), "free_port": str(free_port()),
                  "server_data": str(HERE.parent / "server" / "data")}
        values.update(extra or {})
        return re.sub(r"\{(\w+)\}", lambda m: values.get(m.group(1), m.group(0)), s)

    def run(self, argv, env=None, stdin=None, timeout=PROC_TIMEOUT_S, preexec_fn=None):
        try:
            r = subprocess.run(argv, env=env or self.env, input=stdin, capture_output=True,
                               timeout=timeout, preexec_fn=preexec_fn)
            return r.returncode, (r.stdout + r.stderr).decode(errors="replace")
        except subprocess.TimeoutExpired as e:
            out = ((e.stdout or b"") + (e.stderr or b"")).decode(errors="replace")
            return None, f"still running after {timeout} s (killed): {out}"

    @staticmethod
    def expect_exit(rc, out, exit_code, words, problems, who):
        if rc != exit_code:
            problems.append(f"{who}: exit {rc}, expected {exit_code}: {short(out)}")
        for w in words:
            if w not in out:
                problems.append(f"{who}: the error lacks {w!r}: {short(out)}")

    # -- foamd's command line and config files; listeners beside the running server ---------
    def foamd_case(self, case):
        d = Path(tempfile.mkdtemp(dir=self.tmp))
        files = {}
        for name, content in case.get("files", {}).items():
            p = d / name
            p.write_bytes(to_bytes(self.placeholders(content) if isinstance(content, str)
                                   else content))
            p.chmod(int(str(case.get("file_mode", "600")), 8))
            files[name] = str(p)
        extra = {"case_dir": str(d), "free_port": str(free_port()),
                 **{f"file_{k.replace('.', '_')}": v for k, v in files.items()}}
        args = [self.placeholders(a, extra) for a in case.get("args", [])]
        if "config" in case:
            cfg = d / "foamd.toml"
            cfg.write_text(self.placeholders(case["config"], extra))
            args += ["--config", str(cfg)]
        if not any(a.startswith("--listen") for a in args) and not case.get("config_listen"):
            args += ["--listen", f"127.0.0.1:{free_port()}"]
        db = d / "case.db"
        if not any(a.startswith("--db") for a in args):
            args += ["--db", str(db)]
        rc, out = self.run([str(FOAMD)] + args)
        problems = []
        self.expect_exit(rc, out, case.get("exit", 2), [self.placeholders(w, extra)
                                                        for w in case.get("error", [])], problems,
                         "foamd")
        if case.get("no_db", True) and db.exists():
            problems.append(f"foamd wrote its database {db} before refusing")
        self.outcome(case, problems)

    # -- tokens ----------------------------------------------------------------------------
    def token_case(self, case):
        token = to_bytes(case["token"])
        d = Path(tempfile.mkdtemp(dir=self.tmp))
        f = d / "token"
        f.write_bytes(token)
        f.chmod(0o600)
        words = [w.replace("{file}", str(f)) for w in case.get("error", [])]
        problems = []
        rc, out = self.run([str(FOAMD), "--listen", f"127.0.0.1:{free_port()}", "--db",
                            str(d / "t.db"), "--token-file", str(f)])
        self.expect_exit(rc, out, 2, [f"token file '{f}'"] + words, problems, "foamd")
        if (d / "t.db").exists():
            problems.append("foamd wrote its database before refusing the token")
        rc, out = self.run([str(FOAM), "--token-file", str(f), "list"])
        self.expect_exit(rc, out, 2, [f"token file '{f}'"] + words, problems, "foam --token-file")
        if case.get("env", True) and b"\0" not in token:  # no NUL in an environment
            rc, out = self.run([str(FOAM), "list"], env=dict(self.env, FOAM_TOKEN=token))
            self.expect_exit(rc, out, 2, ["FOAM_TOKEN"] + case.get("env_error", words), problems,
                             "FOAM_TOKEN")
        if activefoam is not None and case.get("python", True):
            try:
                activefoam.Client(f"127.0.0.1:{self.port}",
                                  token=token.decode(errors="surrogateescape")).close()
                problems.append("Python Client(token=...) accepted it")
            except ValueError as e:
                for w in case.get("python_error", []):
                    if w not in str(e):
                        problems.append(f"Python: the ValueError lacks {w!r}: {short(str(e))}")
            except Exception as e:  # noqa: BLE001 — anything but ValueError is the defect
                problems.append(f"Python: {type(e).__name__} instead of ValueError: {short(str(e))}")
        if activefoam is not None:  # the study tool's --token-file
            from activefoam.inputs import read_token_file
            try:
                read_token_file(f)
                problems.append("Python read_token_file accepted it")
            except ValueError as e:
                for w in [f"token file '{f}'"] + words:
                    if w not in str(e):
                        problems.append(f"Python read_token_file: the ValueError lacks {w!r}: "
                                        f"{short(str(e))}")
        self.outcome(case, problems)

    # -- specs -----------------------------------------------------------------------------
    def spec_case(self, case):
        text = to_bytes(case.get("spec", ""))
        fmt = case.get("format", "toml")
        sets = expand(case.get("set", []))
        words = [case["key"]] + case.get("error", []) if "key" in case else case.get("error", [])
        d = Path(tempfile.mkdtemp(dir=self.tmp))
        f = d / f"spec.{fmt}"
        f.write_bytes(text)
        set_args = [a for s in sets for a in ("--set", s)]
        targets = case.get("targets", ["foam-run", "foam", "grpc"])
        if "foam-run" in targets:
            problems = []
            rc, out = self.run([str(FOAM_RUN), str(f), "--out", str(d / "out"), "--quiet"] + set_args)
            self.expect_exit(rc, out, 2, words, problems, "foam-run")
            if (d / "out").exists():
                problems.append("foam-run created its output folder for an invalid spec")
            self.outcome(case, problems, "foam-run")
        if "foam" in targets:
            problems = []
            rc, out = self.run([str(FOAM), "submit", str(f)] + set_args)
            self.expect_exit(rc, out, 2, words, problems, "foam submit")
            self.outcome(case, problems, "foam submit")
        if "grpc" in targets:
            req = service_pb2.SubmitJobRequest(spec_text=text.decode(errors="replace"),
                                               settings=sets)
            self.outcome(case, self.call_problems("SubmitJob", req, "INVALID_ARGUMENT", words),
                         "SubmitJob")

    # -- raw gRPC --------------------------------------------------------------------------
    def call_problems(self, rpc, req, code, words, raw=None):
        problems = []
        try:
            if raw is not None:
                call = self.channel.unary_unary(f"/activefoam.v1.Foam/{rpc}")
                call(raw, timeout=30)
            else:
                method = getattr(self.stub, rpc)
                answer = method(req, timeout=30)
                if rpc in ("WatchJob", "GetSnapshot"):
                    list(answer)
            got, msg = "OK", ""
        except grpc.RpcError as e:
            got, msg = e.code().name, e.details() or ""
        if got != code:
            problems.append(f"{rpc}: {got} {short(msg)!r}, expected {code}")
        for w in words:
            if w not in msg:
                problems.append(f"{rpc}: the message lacks {w!r}: {short(msg)!r}")
        if len(msg) > 1100:
            problems.append(f"{rpc}: a message of {len(msg)} bytes (at most ~1 KB)")
        return problems

    def rpc_case(self, case):
        rpc = case["rpc"]
        code = case.get("code", "INVALID_ARGUMENT")
        raw = to_bytes(case["raw"]) if "raw" in case else None
        req = None
        if raw is None:
            cls = getattr(service_pb2, f"{rpc}Request")
            req = json_format.ParseDict(expand(case.get("request", {})), cls())
        problems = self.call_problems(rpc, req, code, case.get("error", []), raw)
        if code == "OK":
            self.stored += case.get("stores", 0)
        self.outcome(case, problems)

    # -- raw HTTP --------------------------------------------------------------------------
    def http_exchange(self, data, timeout=5):
        t0 = time.monotonic()
        with socket.create_connection(("127.0.0.1", self.http_port), timeout=timeout) as s:
            try:
                s.sendall(data)
            except OSError:
                pass  # the server may answer and close before reading a large body
            chunks = []
            try:
                while True:
                    b = s.recv(65536)
                    if not b:
                        break
                    chunks.append(b)
            except (socket.timeout, ConnectionResetError):
                pass
        return b"".join(chunks).decode(errors="replace"), time.monotonic() - t0

    def http_case(self, case):
        data = to_bytes(self.placeholders(case["request"]) if isinstance(case["request"], str)
                        else case["request"]) + (to_bytes(case["body"]) if "body" in case else b"")
        answer, dt = self.http_exchange(data)
        problems = []
        status = answer.split(" ", 2)[1] if answer.startswith("HTTP/") else "(none)"
        if status != str(case["status"]):
            problems.append(f"status {status}, expected {case['status']}: {short(answer)!r}")
        for w in case.get("error", []):
            if w not in answer:
                problems.append(f"the answer lacks {w!r}: {short(answer)!r}")
        if dt > case.get("within_s", 1.0):
            problems.append(f"answered in {dt:.2f} s (at most {case.get('within_s', 1.0)} s)")
        self.outcome(case, problems)

    def flood_case(self, case):
        """Idle and slow clients on the HTTP port while /healthz is asked: each answer < bound."""
        stop = threading.Event()
        socks = []

        def slow_client():
            while not stop.is_set():
                try:
                    with socket.create_connection(("127.0.0.1", self.http_port), timeout=5) as s:
                        s.sendall(b"GET /jobs HTTP/1.1\r\n")
                        while not stop.wait(case.get("slow_interval_s", 0.5)):
                            s.sendall(b"X-Slow: 1\r\n")
                except OSError:
                    pass  # closed by the server's header deadline: reconnect

        for _ in range(case.get("idle", 100)):
            try:
                socks.append(socket.create_connection(("127.0.0.1", self.http_port), timeout=5))
            except OSError:
                break  # out of descriptors: flood with what we have
        threads = [threading.Thread(target=slow_client, daemon=True)
                   for _ in range(case.get("slow", 20))]
        for t in threads:
            t.start()
        problems, times = [], []
        try:
            time.sleep(0.3)
            for _ in range(case.get("tries", 4)):
                answer, dt = self.http_exchange(
                    b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")
                times.append(dt)
                if not answer.startswith("HTTP/1.1 200"):
                    problems.append(f"/healthz answered {short(answer)!r}")
                time.sleep(case.get("pause_s", 0.3))
        finally:
            stop.set()
            for s in socks:
                s.close()
            for t in threads:
                t.join(timeout=5)
        bound = case.get("within_s", 1.0)
        if max(times, default=0) > bound:
            problems.append(f"/healthz took {', '.join(f'{t:.2f}' for t in times)} s "
                            f"(each at most {bound} s)")
        self.outcome(case, problems)

    # -- the Python client and the study tool -----------------------------------------------
    def python_files(self, case):
        """The case's folder with its `files` (text or expansions; {case_dir} in text) and
        `sparse` files (name = size: a large file without the disk), and the placeholders
        {case_dir} and {file_NAME} (dots as underscores)."""
        d = Path(tempfile.mkdtemp(dir=self.tmp))
        extra = {"case_dir": str(d)}
        for name, content in case.get("files", {}).items():
            p = d / name
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_bytes(to_bytes(self.placeholders(content, extra) if isinstance(content, str)
                                   else content))
            p.chmod(0o600)
            extra[f"file_{name.replace('.', '_').replace('/', '_')}"] = str(p)
        for name, size in case.get("sparse", {}).items():
            with (d / name).open("wb") as fh:
                fh.truncate(size)
        return d, extra

    def study_case(self, case):
        """python3 -m activefoam.study ARGS: the exit status, the words, one line on stderr
        and no traceback, within the time bound, and nothing left at the `absent` paths."""
        d, extra = self.python_files(case)
        args = [self.placeholders(a, extra) for a in case["args"]]
        env = dict(self.env, PYTHONPATH=str(BUILD / "python"))
        env.update({k: self.placeholders(v, extra) for k, v in case.get("env", {}).items()})
        t0 = time.monotonic()
        rc, out = self.run([sys.executable, "-m", "activefoam.study"] + args, env=env,
                           timeout=60, preexec_fn=limit_memory)
        dt = time.monotonic() - t0
        problems = []
        self.expect_exit(rc, out, case.get("exit", 2),
                         [self.placeholders(w, extra) for w in case.get("error", [])], problems,
                         "study")
        if "Traceback" in out or len(out.strip().splitlines()) != 1:
            problems.append(f"study: not one line: {short(out)}")
        if dt > case.get("within_s", PROC_TIMEOUT_S):
            problems.append(f"study: answered in {dt:.1f} s (at most {case.get('within_s')} s)")
        for a in case.get("absent", []):
            p = Path(self.placeholders(a, extra))
            if p.exists():
                problems.append(f"study: {p} was left behind")
        self.outcome(case, problems)

    CLIENT_PROBE = (
        "import json, sys, time\n"
        "import activefoam\n"
        "t0 = time.monotonic()\n"
        "try:\n"
        "    activefoam.Client(**json.loads(sys.argv[1])).close()\n"
        "    print('accepted')\n"
        "except ValueError as e:\n"
        "    print(f'ValueError {time.monotonic() - t0:.3f} {e}')\n"
        "except Exception as e:\n"
        "    print(f'{type(e).__name__} {time.monotonic() - t0:.3f} {e}')\n")

    def client_case(self, case):
        """activefoam.Client(**args) with `env` set (FOAM_* unset otherwise), in a process of
        its own (limit_memory): a ValueError holding the words, within 1 s."""
        d, extra = self.python_files(case)
        kwargs = {k: self.placeholders(v, extra) if isinstance(v, str) else v
                  for k, v in case.get("args", {}).items()}
        env = {k: v for k, v in self.env.items() if k not in ("FOAM_SERVER",)}
        env.update(PYTHONPATH=str(BUILD / "python"))
        env.update({k: self.placeholders(v, extra) for k, v in case.get("env", {}).items()})

        problems = []
        try:
            r = subprocess.run([sys.executable, "-c", self.CLIENT_PROBE, json.dumps(kwargs)],
                               env=env, capture_output=True, timeout=PROC_TIMEOUT_S,
                               preexec_fn=limit_memory)
            out = (r.stdout + r.stderr).decode(errors="replace").strip()
        except subprocess.TimeoutExpired:
            out = f"still running after {PROC_TIMEOUT_S} s (killed)"
        kind, _, rest = out.partition(" ")
        seconds, _, message = rest.partition(" ")
        if kind != "ValueError":
            problems.append(f"Python: {short(out)} (not a ValueError)")
        else:
            for w in case.get("error", []):
                w = self.placeholders(w, extra)
                if w not in message:
                    problems.append(f"Python: the ValueError lacks {w!r}: {short(message)}")
            if float(seconds) > case.get("within_s", 1.0):
                problems.append(f"Python: refused in {seconds} s (at most "
                                f"{case.get('within_s', 1.0)} s)")
        self.outcome(case, problems)

    # -- after the corpus ------------------------------------------------------------------
    def final_checks(self):
        case = {"_file": "after the corpus", "name": "the server still serves, nothing refused "
                "was stored"}
        problems = []
        if self.server.poll() is not None:
            problems.append(f"foamd exited ({self.server.returncode}):\n{self.log.read_text()}")
            self.outcome(case, problems)
            return
        health = self.channel.unary_unary("/grpc.health.v1.Health/Check")
        try:
            if health(b"", timeout=10) != b"\x08\x01":
                problems.append("gRPC health is not SERVING")
        except grpc.RpcError as e:
            problems.append(f"gRPC health: {e.code().name} {e.details()}")
        answer, dt = self.http_exchange(b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        if not answer.startswith("HTTP/1.1 200") or dt > 1:
            problems.append(f"/healthz: {short(answer)!r} in {dt:.2f} s")
        total = self.stub.ListJobs(service_pb2.ListJobsRequest(), timeout=30).total
        if total != self.stored:
            problems.append(f"{total} jobs stored, but the accepted cases stored {self.stored}: "
                            "a refused request was stored")
        d = Path(tempfile.mkdtemp(dir=self.tmp))
        (d / "ok.toml").write_text('scene = "cell"\nduration_s = 1\nsample_every_s = 1\n'
                                   'snapshot_every_s = 0\n[numerics]\ntriangles_per_cell = 80\n')
        rc, out = self.run([str(FOAM), "submit", str(d / "ok.toml"), "--tag", "after-corpus"])
        job = out.strip().splitlines()[0] if rc == 0 and out.strip() else ""
        if rc != 0 or not job:
            problems.append(f"a normal submit: exit {rc}: {short(out)}")
        rc, out = self.run([str(FOAM), "list", "--tag", "after-corpus"])
        if rc != 0 or (job and job not in out):
            problems.append(f"foam list: exit {rc}, the submitted job {job!r} missing: {short(out)}")
        self.outcome(case, problems)

    def close(self):
        self.channel.close()
        self.server.terminate()
        try:
            self.server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.server.kill()
            self.server.wait()
        subprocess.run(["rm", "-rf", str(self.tmp)])


KINDS = {"foamd": Runner.foamd_case, "token": Runner.token_case, "spec": Runner.spec_case,
         "rpc": Runner.rpc_case, "http": Runner.http_case, "flood": Runner.flood_case}
KINDS.update(study=Runner.study_case, client=Runner.client_case)


def load_cases():
    cases = []
    for f in sorted(HERE.glob("*.toml")):
        with f.open("rb") as fh:
            doc = tomllib.load(fh)
        default_kind = doc.get("kind")
        for c in doc.get("case", []):
            c["_file"] = f.name
            c.setdefault("kind", default_kind)
            if c["kind"] not in KINDS:
                sys.exit(f"{f.name}: case {c.get('name')!r}: unknown kind {c['kind']!r}")
            cases.append(c)
    if FILTERS:
        cases = [c for c in cases if any(x in c["_file"] or x in c["name"] for x in FILTERS)]
    return cases


def main():
    cases = load_cases()
    t0 = time.monotonic()
    r = Runner()
    try:
        if activefoam is None:
            print(f"note: the Python client cannot be imported ({PY_CLIENT_MISSING}): its token "
                  "checks are left out")
        for c in cases:
            if c.get("needs") == "ipv6" and not r.ipv6:
                r.skipped.append(f"{c['_file']}: {c['name']} (no ::1 here)")
                continue
            KINDS[c["kind"]](r, c)
        r.final_checks()
    finally:
        r.close()
    dt = time.monotonic() - t0
    print(f"\n{len(cases)} cases: {len(r.passed)} checks held, {len(r.failed)} failed, "
          f"{len(r.xfailed)} known defects (xfail), {len(r.skipped)} skipped; {dt:.1f} s")
    for s in r.skipped:
        print(f"skipped: {s}")
    return 1 if r.failed else 0


if __name__ == "__main__":
    sys.exit(main())
