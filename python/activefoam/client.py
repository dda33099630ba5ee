"""The foamd client: jobs and sweeps in, pandas DataFrames out (see python/README.md)."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import time
import zlib
from pathlib import Path
from typing import Any, Dict, Iterable, Iterator, List, Mapping, Optional, Sequence, Union

import grpc
import pandas as pd

from activefoam import vtk
from activefoam.inputs import (SPEC_MAX_BYTES, host_port_error, read_certificates, read_text,
                               token_error)
from activefoam.v1 import job_pb2, service_pb2, service_pb2_grpc

Spec = Union[Mapping[str, Any], str, os.PathLike]

_STATES = {"queued", "running", "succeeded", "failed", "cancelled"}


def state_name(value: int) -> str:
    """A job state of the wire (activefoam.v1.JobState) as the client names it: "queued",
    "running", "succeeded", "failed" or "cancelled"."""
    return job_pb2.JobState.Name(value)[len("JOB_STATE_"):].lower()


def _state_value(name: str) -> int:
    if name not in _STATES:
        raise ValueError(f"state: {name!r} is not one of {', '.join(sorted(_STATES))}")
    return job_pb2.JobState.Value("JOB_STATE_" + name.upper())


def _error(err: grpc.RpcError, what: str) -> Exception:
    """The Python exception for a failed call, carrying the server's message."""
    code, details = err.code(), err.details() or ""
    text = f"{what}: {details}" if details else f"{what}: {code.name}"
    if code in (grpc.StatusCode.INVALID_ARGUMENT, grpc.StatusCode.FAILED_PRECONDITION,
                grpc.StatusCode.RESOURCE_EXHAUSTED, grpc.StatusCode.OUT_OF_RANGE):
        return ValueError(text)
    if code in (grpc.StatusCode.UNAUTHENTICATED, grpc.StatusCode.PERMISSION_DENIED):
        return PermissionError(text)
    if code == grpc.StatusCode.NOT_FOUND:
        return LookupError(text)
    if code in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.DEADLINE_EXCEEDED):
        return ConnectionError(text)
    return RuntimeError(text)


def flatten(spec: Mapping[str, Any], prefix: str = "") -> Dict[str, Any]:
    """Nested tables → dotted keys ({"cells": {"alpha": 0.5}} → {"cells.alpha": 0.5}), the keys
    `foam-run --keys` lists."""
    out: Dict[str, Any] = {}
    for key, value in spec.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten(value, name + "."))
        else:
            out[name] = value
    return out


def setting(key: str, value: Any) -> str:
    """One key as foamd's settings take it (`foam-run --set`): KEY=VALUE, a boolean as
    true/false, a float exactly (repr)."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, float):
        text = repr(value)
    else:
        text = str(value)
    return f"{key}={text}"


def _settings(flat: Mapping[str, Any]) -> List[str]:
    # The scene first: its table's defaults apply before the other keys.
    keys = sorted(flat, key=lambda k: (k != "scene", 0))
    return [setting(k, flat[k]) for k in keys]


def _spec_fields(spec: Spec, overrides: Optional[Mapping[str, Any]] = None) -> Dict[str, Any]:
    """SubmitJob/SubmitSweep fields for a spec given as a dict or as a TOML/JSON file path, with
    `overrides` set on top."""
    if isinstance(spec, Mapping):
        return {"settings": _settings({**flatten(spec), **flatten(overrides or {})})}
    fields: Dict[str, Any] = {"spec_text": _spec_text(spec)}
    if overrides:
        fields["settings"] = _settings(flatten(overrides))
    return fields


def _spec_text(spec: Union[str, os.PathLike]) -> str:
    # At most 1 MiB whatever the file is (a device or a pipe has no size to check first).
    return read_text(spec, SPEC_MAX_BYTES, "spec")


def _one_tag(tags: Optional[Sequence[str]]) -> str:
    if tags is None:
        return ""
    if isinstance(tags, str):
        return tags
    tags = list(tags)
    if len(tags) > 1:
        raise ValueError(f"tags: a job keeps one tag on the server, got {tags!r}")
    return tags[0] if tags else ""


def _check_token(token: str, what: str = "token") -> None:
    """A bearer token is 16..4096 bytes of printable ASCII without spaces; anything else would
    abort gRPC's metadata check or be refused by foamd (ValueError says which byte)."""
    if not isinstance(token, str):
        raise ValueError(f"{what}: a string, got {type(token).__name__}")
    bad = token_error(token)
    if bad:
        raise ValueError(f"{what} {bad}")


class _Progress:
    """A progress bar on stderr: tqdm where installed (Debian's python3-tqdm), else one line."""

    def __init__(self, label: str, total: int = 0, unit: str = "") -> None:
        self._label, self._total, self._closed = label, total, False
        try:
            from tqdm import tqdm
            self._bar = tqdm(total=total or 1000, desc=label, unit=unit or "‰", file=sys.stderr,
                             leave=True, bar_format=None if total else
                             "{desc}: {percentage:3.0f}%|{bar}| {postfix}")
        except ImportError:
            self._bar = None

    def update(self, fraction: float, what: str, t_s: Optional[float] = None) -> None:
        note = what + ("" if t_s is None else f", t = {t_s:.6g} s")
        if self._bar is not None:
            n = round(fraction * (self._total or 1000))
            self._bar.update(n - self._bar.n)
            self._bar.set_postfix_str(note)
        else:
            bar = int(20 * fraction)
            print(f"\r{self._label} [{'#' * bar}{'.' * (20 - bar)}] {100 * fraction:5.1f}%  {note}",
                  end="", file=sys.stderr, flush=True)

    def close(self, final: str = "") -> None:
        if self._closed:
            return
        self._closed = True
        if self._bar is not None:
            if final:
                self._bar.set_postfix_str(final)
            self._bar.close()
        else:
            print(f"  {final}" if final else "", file=sys.stderr)


class Client:
    """A connection to foamd. Defaults from FOAM_SERVER, FOAM_TOKEN, FOAM_TLS_CA.

    server: HOST:PORT, the port in 1..65535; token: the bearer token (the server's
    --token-file; a FOAM_TOKEN that is set must hold one: set but empty is an error, not "no
    token"); tls_ca: PEM file of the server's certificate or CA (its --tls-cert), at most 1 MiB.
    A token without TLS is sent over local TCP credentials, which gRPC allows to loopback
    addresses only (as foam does). ValueError names what is wrong with any of them.
    """

    def __init__(self, server: Optional[str] = None, token: Optional[str] = None,
                 tls_ca: Optional[str] = None, timeout_s: float = 60.0):
        self.server = server or os.environ.get("FOAM_SERVER") or "127.0.0.1:50051"
        bad = host_port_error(self.server)
        if bad:
            raise ValueError(f"{'server' if server else 'FOAM_SERVER'}: {bad}")
        if token is not None:
            _check_token(token)
        elif "FOAM_TOKEN" in os.environ:
            # Set but empty is a mistake, not "no auth": the token would go unsent in silence.
            token = os.environ["FOAM_TOKEN"]
            _check_token(token, "FOAM_TOKEN")
        if tls_ca is None:
            tls_ca = os.environ.get("FOAM_TLS_CA") or None
            ca_what = "FOAM_TLS_CA"
        else:
            ca_what = "tls_ca"
        self.timeout_s = timeout_s
        self._token, self._tls_ca = token, tls_ca  # for `foam` run on this client's behalf
        options = [("grpc.max_receive_message_length", 64 << 20)]
        if tls_ca is not None:  # tls_ca="" is a mistake, not "no TLS"
            creds = grpc.ssl_channel_credentials(
                root_certificates=read_certificates(tls_ca, ca_what))
            if token:
                creds = grpc.composite_channel_credentials(
                    creds, grpc.access_token_call_credentials(token))
            self._channel = grpc.secure_channel(self.server, creds, options)
        elif token:
            creds = grpc.composite_channel_credentials(
                grpc.local_channel_credentials(grpc.LocalConnectionType.LOCAL_TCP),
                grpc.access_token_call_credentials(token))
            self._channel = grpc.secure_channel(self.server, creds, options)
        else:
            self._channel = grpc.insecure_channel(self.server, options)
        self._stub = service_pb2_grpc.FoamStub(self._channel)

    def close(self) -> None:
        self._channel.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _call(self, method: str, request: Any, what: str) -> Any:
        try:
            return getattr(self._stub, method)(request, timeout=self.timeout_s)
        except grpc.RpcError as e:
            raise _error(e, what) from None

    # ---- jobs --------------------------------------------------------------------------------

    def submit(self, spec: Spec, preset: Optional[str] = None, tags: Optional[Sequence[str]] = None,
               priority: int = 0, idempotency_key: str = "",
               overrides: Optional[Mapping[str, Any]] = None) -> "Job":
        """Submits one job: `spec` is a dict of spec keys (dotted or nested tables, as
        `foam-run --keys` lists them) or the path of a TOML/JSON spec file; `overrides`, keys
        set on top of it (as `foam-run --set`). A second submit with the same idempotency_key
        returns the first one's job; the Job's `created` says which happened."""
        fields = _spec_fields(spec, overrides)
        if preset:
            fields.setdefault("settings", []).insert(0, f"numerics.preset={preset}")
        req = service_pb2.SubmitJobRequest(priority=priority, tag=_one_tag(tags),
                                           idempotency_key=idempotency_key, **fields)
        resp = self._call("SubmitJob", req, "submit")
        return Job(self, resp.job_id, created=resp.created)

    def resolve(self, spec: Spec, preset: Optional[str] = None,
                overrides: Optional[Mapping[str, Any]] = None) -> Any:
        """The spec a submit of the same arguments would run, resolved by foamd's engine, without
        submitting anything: the ResolveSpecResponse, whose spec_json holds every key (as a
        job's resolved_spec_json does) and whose labels name the keys that only choose other
        keys' values (the preset, the accuracy targets). A spec foamd would refuse raises the
        submit's ValueError, naming the key."""
        fields = _spec_fields(spec, overrides)
        if preset:
            fields.setdefault("settings", []).insert(0, f"numerics.preset={preset}")
        return self._call("ResolveSpec", service_pb2.ResolveSpecRequest(**fields), "resolve")

    def job(self, job_id: str) -> "Job":
        return Job(self, job_id)

    def cancel(self, job_id: str, reason: str = "") -> str:
        """Cancels a queued or running job; returns its state (a running job stops at its next
        step: "running" until then)."""
        j = self._call("CancelJob", service_pb2.CancelJobRequest(job_id=job_id, reason=reason),
                       f"cancel {job_id}")
        return state_name(j.state)

    def job_infos(self, **filters: Any) -> List[Any]:
        """The job messages (as Job.info() returns them: state, seed, spec_json,
        resolved_spec_json, failure_kind, ...) of every job matching ListJobsRequest's filters
        (tag, sweep_id, states, scene, outcome), newest first, over all pages."""
        req = service_pb2.ListJobsRequest(page_size=1000, **filters)
        jobs: List[Any] = []
        while True:
            resp = self._call("ListJobs", req, "list jobs")
            jobs.extend(resp.jobs)
            if not resp.next_page_token:
                return jobs
            req.page_token = resp.next_page_token

    def jobs(self, state: Union[str, Iterable[str], None] = None, tag: str = "",
             sweep: str = "", scene: str = "", outcome: str = "") -> pd.DataFrame:
        """The jobs matching the filters, newest first, one row each."""
        states = [state] if isinstance(state, str) else list(state or [])
        rows = [_job_row(j) for j in self.job_infos(
            states=[_state_value(s) for s in states], tag=tag, sweep_id=sweep, scene=scene,
            outcome=outcome)]
        return pd.DataFrame(rows, columns=_JOB_COLUMNS)

    # ---- sweeps ------------------------------------------------------------------------------

    def sweep(self, spec: Spec, grid: Optional[Mapping[str, Sequence[Any]]] = None,
              seeds: Optional[Sequence[int]] = None, preset: Optional[str] = None,
              tags: Optional[Sequence[str]] = None, name: str = "", priority: int = 0,
              idempotency_key: str = "") -> "Sweep":
        """Submits base spec × the cartesian product of `grid` × `seeds`, one job each."""
        fields = _spec_fields(spec)
        if preset:
            fields.setdefault("settings", []).insert(0, f"numerics.preset={preset}")
        axes = [service_pb2.GridAxis(key=k, values=[setting(k, v).split("=", 1)[1] for v in vs])
                for k, vs in (grid or {}).items()]
        req = service_pb2.SubmitSweepRequest(grid=axes, seeds=list(seeds or []),
                                             tag=_one_tag(tags), name=name, priority=priority,
                                             idempotency_key=idempotency_key, **fields)
        resp = self._call("SubmitSweep", req, "sweep")
        return Sweep(self, resp.sweep_id, list(resp.job_ids), list((grid or {}).keys()))

    def sweep_of(self, sweep_id: str, keys: Sequence[str] = ()) -> "Sweep":
        """An existing sweep; `keys`: the spec keys for the columns of results() (default: the
        keys its grid varies, as the server recorded them)."""
        ids = [j.id for j in reversed(self.job_infos(sweep_id=sweep_id))]
        return Sweep(self, sweep_id, ids, list(keys))


_JOB_COLUMNS = ["job_id", "state", "scene", "outcome", "seed", "progress", "t_s", "tag",
                "sweep_id", "reason", "created_utc", "finished_utc"]


def _job_row(j: Any) -> Dict[str, Any]:
    return {"job_id": j.id, "state": state_name(j.state), "scene": j.scene,
            "outcome": j.outcome or None, "seed": j.seed, "progress": j.progress, "t_s": j.t_s,
            "tag": j.tag, "sweep_id": j.sweep_id, "reason": j.reason,
            "created_utc": j.created_utc, "finished_utc": j.finished_utc or None}


def _spec_value(spec_json: str, key: str) -> Any:
    value: Any = json.loads(spec_json)
    for part in key.split("."):
        if not isinstance(value, dict) or part not in value:
            return None
        value = value[part]
    return value


class Job:
    """A job of foamd. `created`: for a job from Client.submit, whether that call created it
    (False: an earlier submit with the same idempotency key had); None otherwise."""

    def __init__(self, client: Client, job_id: str, created: Optional[bool] = None):
        self._c = client
        self.id = job_id
        self.created = created

    def __repr__(self) -> str:
        return f"Job({self.id!r})"

    def info(self) -> Any:
        """The job message (state, progress, spec_json and resolved_spec_json, outcome, ...)."""
        return self._c._call("GetJob", service_pb2.GetJobRequest(job_id=self.id),
                             f"job {self.id}")

    def state(self) -> str:
        return state_name(self.info().state)

    def _events(self, from_seq: int = 0, timeout_s: Optional[float] = None) -> Iterator[Any]:
        """The job's events (WatchJob, following) until it ends. A stream that ends before the
        job did (foamd restarting) is opened again from the last event seen, as `foam watch`
        does; TimeoutError once timeout_s has passed."""
        start = time.monotonic()
        seq = from_seq
        while True:
            left = None if timeout_s is None else timeout_s - (time.monotonic() - start)
            if left is not None and left <= 0:
                raise TimeoutError(f"job {self.id} had not ended after {timeout_s} s")
            ended = False
            try:
                for ev in self._c._stub.WatchJob(
                        service_pb2.WatchJobRequest(job_id=self.id, from_seq=seq, follow=True),
                        timeout=left):
                    seq = max(seq, ev.seq)
                    yield ev
                    if ev.WhichOneof("kind") == "state" and ev.state.terminal:
                        ended = True
                        return
            except grpc.RpcError as e:
                if e.code() == grpc.StatusCode.DEADLINE_EXCEEDED:
                    raise TimeoutError(f"job {self.id} had not ended after {timeout_s} s") from None
                if e.code() != grpc.StatusCode.UNAVAILABLE:
                    raise _error(e, f"job {self.id}") from None
            if not ended:
                if self.info().terminal:  # ended between two streams
                    return
                time.sleep(0.5)

    def wait(self, progress: bool = False, poll_s: float = 0.5,
             timeout_s: Optional[float] = None) -> str:
        """Waits until the job ends and returns its final state (succeeded, failed, cancelled),
        following the server's event stream (nothing is polled; poll_s is kept for old callers).
        progress=True shows a progress bar on stderr (tqdm where installed, else one line)."""
        bar = _Progress(self.id) if progress else None
        state = ""
        try:
            for ev in self._events(timeout_s=timeout_s):
                kind = ev.WhichOneof("kind")
                if kind == "state":
                    state = state_name(ev.state.state)
                    if bar:
                        bar.update(ev.state.progress, state, ev.state.t_s)
                    if ev.state.terminal and bar:
                        bar.close(state + (f": {ev.state.reason}" if ev.state.reason else ""))
                elif kind == "progress" and bar:
                    bar.update(ev.progress.fraction, "running", ev.progress.t_s)
        finally:
            if bar:
                bar.close()
        return state or self.state()

    def watch(self) -> Iterator[Dict[str, float]]:
        """Yields the job's samples as they arrive (column name → value, the columns of
        samples()), from its first, until the job ends: a notebook can plot θ(t) live."""
        columns: List[str] = []
        for ev in self._events():
            if ev.WhichOneof("kind") != "sample":
                continue
            if ev.columns:
                columns = list(ev.columns)
            yield dict(zip(columns, ev.sample.values))

    def snapshot(self, index: int = -1) -> Dict[str, Any]:
        """Snapshot `index` (-1: the latest) as numpy arrays: "x" (vertices × 3, µm), "tri"
        (triangles × 3, vertex indices), "cell" (the cell of each vertex), "pressure" and
        "label" (per cell), and "t_s", "step"."""
        import numpy as np
        if index < 0:
            snaps = self.results_message(False).snapshots
            if not snaps:
                raise LookupError(f"job {self.id} has no snapshots")
            index = snaps[-1].index
        snap = job_pb2.SnapshotData()
        data = self._snapshot_bytes(index)
        try:
            snap.ParseFromString(data)
        except Exception as e:  # protobuf's DecodeError: damaged, not a client bug
            raise RuntimeError(f"snapshot {index} of {self.id} is damaged: {len(data)} bytes "
                               f"that are not a SnapshotData ({e})") from None
        return {"t_s": snap.t_s, "step": snap.step,
                "x": np.array(snap.x, dtype=float).reshape(-1, 3),
                "tri": np.array(snap.tri, dtype=np.int64).reshape(-1, 3),
                "cell": np.array(snap.vertex_cell, dtype=np.int64),
                "pressure": np.array(snap.cell_pressure, dtype=float),
                "label": np.array(snap.cell_label, dtype=np.int64)}

    def results_message(self, with_samples: bool = False) -> Any:
        """The job's GetResults message in one call: the job, its results, the sample columns
        and (with_samples) rows, its snapshots' list and its curves."""
        return self._c._call("GetResults",
                             service_pb2.GetResultsRequest(job_id=self.id,
                                                           with_samples=with_samples),
                             f"results {self.id}")

    def samples(self) -> pd.DataFrame:
        """The samples (the columns of samples.csv), one row per sample."""
        r = self.results_message(True)
        return pd.DataFrame([list(s.values) for s in r.samples], columns=list(r.columns))

    def results(self) -> Dict[str, float]:
        """Result name → value (fits with their *_se standard errors; NaN where undefined)."""
        return {x.name: x.value for x in self.results_message(False).results}

    def curve(self, name: str = "msrd") -> pd.DataFrame:
        """A curve the finished run ended with, as columns x, y: "msrd" (fusion) is the MSRD
        (µm², y) against the lag (s, x); a probe's by its name (observe.msrd_by_depth:
        "msrd_surface", "msrd_mixed", "msrd_buried", "msrd_layer0", "msrd_layer1",
        "msrd_layer2plus", the same axes). LookupError when the run has none (not finished, not
        a fusion, its probe not asked for, or run by a foamd older than the curves)."""
        for c in self.results_message(False).curves:
            if c.name == name:
                return pd.DataFrame({"x": list(c.x), "y": list(c.y)})
        raise LookupError(f"job {self.id} has no curve {name!r}")

    def export(self, directory: Union[str, os.PathLike]) -> List[Path]:
        """Writes the snapshots as VTK PolyData (snap_NNNNNN.vtp) and series.pvd, as
        `foam export` does; returns the files written."""
        r = self.results_message(False)
        if not r.snapshots:
            raise LookupError(f"job {self.id} has no snapshots (snapshot_every_s = 0, or none "
                              "recorded yet)")
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        series, written = [], []
        for info in r.snapshots:
            data = self._snapshot_bytes(info.index)
            snap = job_pb2.SnapshotData()
            try:
                snap.ParseFromString(data)
            except Exception as e:  # protobuf's DecodeError: damaged, not a client bug
                raise RuntimeError(f"snapshot {info.index} of {self.id} is damaged: {len(data)} "
                                   f"bytes that are not a SnapshotData ({e})") from None
            name = f"snap_{info.index:06d}.vtp"
            (out / name).write_text(vtk.polydata(snap))
            series.append((snap.t_s, name))
            written.append(out / name)
        (out / "series.pvd").write_text(vtk.collection(series))
        return written + [out / "series.pvd"]

    def movie(self, path: Union[str, os.PathLike], fps: float = 4, size: Sequence[int] = (1280, 720),
              color: str = "spheroid", foam: Optional[str] = None) -> Path:
        """Renders the snapshots to a video, `path` ending in .mp4 or .gif: one frame a snapshot,
        a fixed camera on both spheroids, the simulated time in a corner; `color` is spheroid,
        cell, pressure or volume, as on the dashboard. It runs `foam export --movie` (its
        renderer, and Debian's ffmpeg), connected as this client is; `foam` names the
        executable (default: $FOAM_EXE, else foam on PATH). Returns the path.

        LookupError when the job has no snapshots (or does not exist), FileNotFoundError when
        foam or ffmpeg is missing, ValueError for a bad argument, RuntimeError otherwise; each
        with foam's message."""
        if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not \
                (math.isfinite(fps) and fps > 0):  # `--fps nan` reached ffmpeg
            raise ValueError(f"fps: a positive number of frames a second, got {fps!r}")
        exe = foam or os.environ.get("FOAM_EXE") or shutil.which("foam")
        if not exe:
            raise FileNotFoundError("Job.movie runs `foam export --movie`: no foam executable "
                                    "(pass foam=..., set FOAM_EXE or put foam on PATH)")
        width, height = size
        args = [exe, "--server", self._c.server]
        env = dict(os.environ)
        # The token goes by the environment: a command line is readable by every local user.
        env.pop("FOAM_TOKEN", None)
        env.pop("FOAM_TLS_CA", None)
        if self._c._token:
            env["FOAM_TOKEN"] = self._c._token
        if self._c._tls_ca:
            args += ["--tls-ca", str(self._c._tls_ca)]
        args += ["export", "--movie", self.id, str(path), "--fps", str(fps),
                 "--size", f"{int(width)}x{int(height)}", "--color", color]
        try:
            r = subprocess.run(args, capture_output=True, text=True, env=env)
        except OSError as e:
            raise FileNotFoundError(f"cannot run {exe}: {e}") from None
        if r.returncode != 0:
            message = (r.stderr.strip() or r.stdout.strip()).removeprefix("foam: ")
            if "no snapshots" in message or r.returncode == 5:
                raise LookupError(message)
            if "ffmpeg is not on PATH" in message:
                raise FileNotFoundError(message)
            if r.returncode == 2:
                raise ValueError(message)
            if r.returncode == 4:
                raise PermissionError(message)
            raise RuntimeError(message)
        return Path(path)

    def _snapshot_bytes(self, index: int) -> bytes:
        chunks, compression = [], ""
        try:
            for k, chunk in enumerate(self._c._stub.GetSnapshot(
                    service_pb2.GetSnapshotRequest(job_id=self.id, index=index),
                    timeout=self._c.timeout_s)):
                if k == 0:
                    compression = chunk.compression
                chunks.append(chunk.data)
        except grpc.RpcError as e:
            raise _error(e, f"snapshot {index} of {self.id}") from None
        data = b"".join(chunks)
        if compression == "zlib":
            try:
                return zlib.decompress(data)
            except zlib.error as e:  # a damaged snapshot in the store: say which, as foam does
                raise RuntimeError(f"snapshot {index} of {self.id} is damaged: {len(data)} "
                                   f"compressed bytes that do not inflate ({e})") from None
        if compression:
            raise RuntimeError(f"snapshot {index}: unknown compression {compression!r}")
        return data


class Sweep:
    def __init__(self, client: Client, sweep_id: str, job_ids: List[str], keys: List[str]):
        self._c = client
        self.id = sweep_id
        self.keys = keys
        self.jobs = [Job(client, i) for i in job_ids]

    def __repr__(self) -> str:
        return f"Sweep({self.id!r}, {len(self.jobs)} jobs)"

    def wait(self, progress: bool = False, poll_s: float = 1.0,
             timeout_s: Optional[float] = None) -> Dict[str, int]:
        """Waits until every job has ended, following each job's event stream in turn (nothing
        is polled; poll_s is kept for old callers); returns the count per final state."""
        start = time.monotonic()
        counts: Dict[str, int] = {}
        bar = _Progress(f"sweep {self.id}", total=len(self.jobs), unit="jobs") if progress else None
        try:
            for k, job in enumerate(self.jobs):
                left = None if timeout_s is None else timeout_s - (time.monotonic() - start)
                try:
                    state = job.wait(timeout_s=left)
                except TimeoutError:
                    raise TimeoutError(f"sweep {self.id}: {k} of {len(self.jobs)} jobs ended "
                                       f"after {timeout_s} s") from None
                counts[state] = counts.get(state, 0) + 1
                if bar:
                    parts = ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
                    bar.update((k + 1) / len(self.jobs), parts)
        finally:
            if bar:
                bar.close()
        return counts

    def results(self, metrics: Optional[Sequence[str]] = None) -> pd.DataFrame:
        """One row per job: job_id, state, outcome, seed, the swept keys (dotted), then its
        results (NaN for jobs that did not succeed)."""
        jobs = list(reversed(self._c.job_infos(sweep_id=self.id)))  # in submission order
        q = self._c._call("QueryResults",
                          service_pb2.QueryResultsRequest(sweep_id=self.id, limit=100000,
                                                          names=list(metrics or [])),
                          f"results of sweep {self.id}")
        if not self.keys:  # an existing sweep: the server knows what it varies
            self.keys = list(q.swept_keys)
        values = {row.job_id: {r.name: r.value for r in row.results} for row in q.rows}
        names = sorted({n for v in values.values() for n in v})
        rows = []
        for j in jobs:
            row: Dict[str, Any] = {"job_id": j.id, "state": state_name(j.state),
                                   "outcome": j.outcome or None, "seed": j.seed}
            for k in self.keys:
                row[k] = _spec_value(j.spec_json, k)
            got = values.get(j.id, {})
            for n in names:
                row[n] = got.get(n, math.nan)
            rows.append(row)
        return pd.DataFrame(rows, columns=["job_id", "state", "outcome", "seed", *self.keys,
                                           *names])

    def summary(self, by: Sequence[str], metrics: Optional[Sequence[str]] = None) -> pd.DataFrame:
        """Per value of the `by` keys, over seeds: jobs, failed (failed or cancelled), and per
        metric n (finite values of succeeded jobs), median, q25, q75 — columns
        METRIC_n, METRIC_median, METRIC_q25, METRIC_q75 (the layout of foam results --by)."""
        by = list(by)
        df = self.results(metrics)
        missing = [k for k in by if k not in df.columns]
        if missing:
            # Keys not swept: read them from each job's spec.
            jobs = {j.id: j for j in self._c.job_infos(sweep_id=self.id)}
            for k in missing:
                df[k] = [_spec_value(jobs[i].spec_json, k) for i in df["job_id"]]
                if df[k].isna().all():
                    raise ValueError(f"by: {k!r} is not a key of this sweep's specs (dotted, as "
                                     "foam-run --keys lists them, e.g. cells.alpha)")
        names = list(metrics) if metrics else [
            c for c in df.columns if c not in {"job_id", "state", "outcome", "seed", *self.keys,
                                               *by}]
        out = []
        for key, g in df.groupby(by if len(by) > 1 else by[0], sort=True):
            key = key if isinstance(key, tuple) else (key,)
            row: Dict[str, Any] = dict(zip(by, key))
            row["jobs"] = len(g)
            row["succeeded"] = int((g["state"] == "succeeded").sum())
            row["failed"] = int(g["state"].isin(["failed", "cancelled"]).sum())
            ok = g[g["state"] == "succeeded"]
            for n in names:
                v = ok[n].astype(float) if n in ok else pd.Series(dtype=float)
                v = v[v.apply(math.isfinite)]
                row[f"{n}_n"] = len(v)
                row[f"{n}_median"] = v.quantile(0.5) if len(v) else math.nan
                row[f"{n}_q25"] = v.quantile(0.25) if len(v) else math.nan
                row[f"{n}_q75"] = v.quantile(0.75) if len(v) else math.nan
            out.append(row)
        return pd.DataFrame(out)
