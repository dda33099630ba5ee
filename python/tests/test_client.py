"""The Python client against a real foamd: jobs, samples, results, export, sweeps and their
summary over seeds, and errors mapped to Python exceptions."""

import json
import math
import os

import pandas as pd
import pytest

from activefoam import Client
from conftest import Foamd, _free_port

TINY = {"scene": "cell", "duration_s": 5, "sample_every_s": 1, "snapshot_every_s": 5,
        "numerics": {"triangles_per_cell": 80}}


def test_submit_wait_samples_results_export(client, tmp_path):
    job = client.submit(TINY, tags=["py"])
    assert job.wait(timeout_s=120) == "succeeded"
    assert job.state() == "succeeded"
    samples = job.samples()
    assert isinstance(samples, pd.DataFrame)
    assert list(samples.columns[:2]) == ["t_s", "steps"]
    assert "aspect_ratio" in samples.columns
    assert samples["t_s"].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    results = job.results()
    assert results["t_s"] == 5.0
    assert math.isclose(results["aspect_ratio"], samples["aspect_ratio"].iloc[-1], rel_tol=1e-12)
    files = job.export(tmp_path / "vtk")
    names = sorted(f.name for f in files)
    assert names == ["series.pvd", "snap_000000.vtp", "snap_000001.vtp"]
    text = (tmp_path / "vtk" / "snap_000001.vtp").read_text()
    assert 'NumberOfPolys="80"' in text and 'Name="pressure"' in text
    assert 'file="snap_000001.vtp"' in (tmp_path / "vtk" / "series.pvd").read_text()
    jobs = client.jobs(tag="py")
    assert jobs["job_id"].tolist() == [job.id]
    assert jobs["state"].tolist() == ["succeeded"]


def test_nested_tables_dotted_keys_and_spec_files_are_the_same_spec(client, tmp_path):
    spec_file = tmp_path / "cell.toml"
    spec_file.write_text('scene = "cell"\nduration_s = 2\nsample_every_s = 1\n'
                         'snapshot_every_s = 0\n[numerics]\ntriangles_per_cell = 80\n'
                         '[cells]\ngamma = 0.6\n')
    dotted = dict(TINY, duration_s=2, snapshot_every_s=0, **{"cells.gamma": 0.6})
    nested = dict(TINY, duration_s=2, snapshot_every_s=0, cells={"gamma": 0.6})
    jobs = [client.submit(s) for s in (spec_file, dotted, nested)]
    for j in jobs:
        assert j.wait(timeout_s=120) == "succeeded"
    specs = [j.info().spec_json for j in jobs]
    assert specs[0] == specs[1] == specs[2]
    frames = [j.samples().drop(columns=["wall_s"]) for j in jobs]
    pd.testing.assert_frame_equal(frames[0], frames[1])
    pd.testing.assert_frame_equal(frames[0], frames[2])


def test_a_probes_columns_come_with_the_samples(client):
    # [observe] asks for a probe: its columns follow the scene's, the samples unchanged by it.
    base = dict(TINY, duration_s=2, snapshot_every_s=0,
                numerics={"triangles_per_cell": 80, "cg_tol": 1e-8})
    plain = client.submit(base)
    probed = client.submit(dict(base, observe={"dissipation": True}))
    for j in (plain, probed):
        assert j.wait(timeout_s=120) == "succeeded"
    a, b = plain.samples(), probed.samples()
    added = [c for c in b.columns if c not in a.columns]
    assert added[:7] == ["diss_medium_nw", "diss_cortex_nw", "diss_friction_t_nw",
                         "diss_friction_n_nw", "diss_springs_nw", "power_forces_nw",
                         "power_active_nw"]
    assert "diss_cortex_affine_nw" in added[7:]  # each cell's affine part, after the seven
    assert list(b.columns[:len(a.columns)]) == list(a.columns)
    pd.testing.assert_frame_equal(a.drop(columns=["wall_s"]),
                                  b[a.columns].drop(columns=["wall_s"]))
    assert math.isnan(b["diss_medium_nw"].iloc[0])  # t = 0: no step yet
    later = b.iloc[1:]
    assert (later["diss_medium_nw"] > 0).all() and (later["diss_cortex_nw"] > 0).all()
    balance = (later["diss_medium_nw"] + later["diss_cortex_nw"]) / later["power_forces_nw"]
    assert ((balance - 1).abs() < 1e-4).all()


def test_a_probes_curves_come_with_the_results(client):
    # observe.msrd_by_depth ends a fusion with curves of its own, read by name as "msrd" is. No
    # cell of 3 + 4 is buried: the surface pairs are all the pairs.
    job = client.submit({"scene": "fusion", "duration_s": 4, "sample_every_s": 1,
                         "snapshot_every_s": 0, "scene.n_cells_a": 3, "scene.n_cells_b": 4,
                         "scene.prep_max_s": 10, "scene.allow_uncompacted": True,
                         "numerics": {"triangles_per_cell": 80, "dt_s": 0.2},
                         "observe": {"msrd_by_depth": True}})
    assert job.wait(timeout_s=120) == "succeeded"
    msrd, surface = job.curve("msrd"), job.curve("msrd_surface")
    assert len(msrd) > 0 and list(surface["x"]) == list(msrd["x"])
    assert ((surface["y"] - msrd["y"]).abs() <= 1e-12 * msrd["y"]).all()
    assert len(job.curve("msrd_buried")) == 0
    samples = job.samples()
    assert (samples["cells_buried"] == 0).all() and (samples["cells_surface"] == 7).all()
    r = job.results()
    assert r["mixing_time_surface_s"] == r["mixing_time_s"]
    assert math.isnan(r["mixing_time_buried_s"])


def test_sweep_results_and_summary_over_seeds(client):
    base = dict(TINY, snapshot_every_s=0)
    sw = client.sweep(base, grid={"cells.gamma": [0.4, 0.6]}, seeds=[1, 2], tags=["sw"])
    assert len(sw.jobs) == 4
    assert sw.wait(timeout_s=300) == {"succeeded": 4}
    table = sw.results(metrics=["aspect_ratio", "wall_s"])
    assert list(table.columns) == ["job_id", "state", "outcome", "seed", "cells.gamma",
                                   "aspect_ratio", "wall_s"]
    assert sorted(table["cells.gamma"].tolist()) == [0.4, 0.4, 0.6, 0.6]
    assert sorted(table["seed"].tolist()) == [1, 1, 2, 2]
    summary = sw.summary(by=["cells.gamma"], metrics=["wall_s"])
    assert summary["cells.gamma"].tolist() == [0.4, 0.6]
    assert summary["jobs"].tolist() == [2, 2]
    assert summary["failed"].tolist() == [0, 0]
    for gamma, row in zip([0.4, 0.6], summary.itertuples(index=False)):
        values = sorted(table.loc[table["cells.gamma"] == gamma, "wall_s"])
        assert row.wall_s_n == 2
        assert row.wall_s_median == pytest.approx((values[0] + values[1]) / 2, rel=1e-12)
        assert row.wall_s_q25 == pytest.approx(values[0] + 0.25 * (values[1] - values[0]))
        assert row.wall_s_q75 == pytest.approx(values[0] + 0.75 * (values[1] - values[0]))
    with pytest.raises(ValueError, match="'cells.nope' is not a key"):
        sw.summary(by=["cells.nope"])
    again = client.sweep_of(sw.id)  # the swept keys from the server
    pd.testing.assert_frame_equal(again.results(metrics=["aspect_ratio"]),
                                  sw.results(metrics=["aspect_ratio"]))


def test_a_prepare_table_in_a_dict_is_the_specs_prepare_table(client):
    # The spheroids prepared at an L_eta/r of their own: nested or dotted, the same spec, whose
    # preparation runs at what a plain run at that L_eta/r has; a key it cannot hold is refused.
    nested = {"scene": "fusion", "cells": {"l_eta_reduced": 2},
              "prepare": {"cells": {"l_eta_reduced": 0.5}}}
    dotted = {"scene": "fusion", "cells.l_eta_reduced": 2,
              "prepare": {"cells.l_eta_reduced": 0.5}}
    plain = {"scene": "fusion", "cells": {"l_eta_reduced": 0.5}}
    a, b, c = (json.loads(client.resolve(s).spec_json) for s in (nested, dotted, plain))
    assert a == b
    assert a["prepare"]["cells"]["xi"] == c["cells"]["xi"] != a["cells"]["xi"]
    assert "prepare" not in c
    with pytest.raises(ValueError, match=r"prepare\.numerics\.cg_tol"):
        client.resolve({"scene": "fusion", "prepare": {"numerics": {"cg_tol": 1e-4}}})


def test_errors_are_python_exceptions_with_the_servers_message(client, tmp_path):
    with pytest.raises(ValueError, match="cells.gamma"):
        client.submit(dict(TINY, **{"cells.gamma": -1}))
    with pytest.raises(ValueError, match="is a directory"):
        client.submit(tmp_path)
    with pytest.raises(ValueError, match="one tag"):
        client.submit(TINY, tags=["a", "b"])
    with pytest.raises(LookupError, match="no job"):
        client.job("j-nope").state()
    with pytest.raises(ValueError, match="state"):
        client.jobs(state="sleeping")
    with Client(f"127.0.0.1:{_free_port()}", timeout_s=2) as nobody:
        with pytest.raises(ConnectionError):
            nobody.jobs()


def test_token_auth(tmp_path):
    secret = "py-test-token-0123456789"
    d = Foamd(tmp_path, token=secret)
    try:
        with Client(d.address, timeout_s=5) as anonymous:
            with pytest.raises(PermissionError):
                anonymous.jobs()
        with Client(d.address, token="wrong-token-0123456789", timeout_s=5) as wrong:
            with pytest.raises(PermissionError):
                wrong.jobs()
        os.environ["FOAM_TOKEN"] = secret
        try:
            with Client(d.address) as c:  # the token from FOAM_TOKEN
                job = c.submit(dict(TINY, snapshot_every_s=0))
                assert job.wait(timeout_s=120) == "succeeded"
        finally:
            del os.environ["FOAM_TOKEN"]
        if os.environ.get("FOAM_EXE"):
            # Job.movie hands the client's token to foam: the job is found (and has no
            # snapshots); with a wrong token foam is refused.
            with Client(d.address, token=secret, timeout_s=5) as c:
                with pytest.raises(LookupError, match="no snapshots"):
                    c.job(job.id).movie(tmp_path / "m.mp4")
            with Client(d.address, token="wrong-token-0123456789", timeout_s=5) as wrong:
                with pytest.raises(PermissionError):
                    wrong.job(job.id).movie(tmp_path / "m.mp4")
    finally:
        d.stop()


@pytest.mark.parametrize("token", ["short", "x" * 5000, "good-token-0123456\n", "tok\x00en-0123456789",
                                   "tökén-0123456789abc", "with space 0123456789"])
def test_tokens_that_cannot_be_sent_are_refused_at_once(token):
    # Binary bytes or a newline made gRPC abort the client; 1 MB broke every call.
    with pytest.raises(ValueError, match="token"):
        Client("127.0.0.1:1", token=token)


def test_a_spec_without_a_size_is_read_to_its_limit_only():
    # /dev/zero has no size to check first; the client reads at most 1 MiB.
    with Client("127.0.0.1:1") as c, pytest.raises(ValueError, match="more than the 1 MiB"):
        c.submit("/dev/zero")


class _FakeChunk:
    def __init__(self, data, compression):
        self.data, self.compression = data, compression


class _FakeStub:
    def __init__(self, chunks):
        self._chunks = chunks

    def GetSnapshot(self, req, timeout=None):
        return iter(self._chunks)


def test_a_damaged_snapshot_is_a_runtime_error_naming_it():
    # zlib.error escaped Job.export, not one of the client's documented exceptions.
    from activefoam.client import Job
    c = Client("127.0.0.1:1")
    c._stub = _FakeStub([_FakeChunk(b"\x78\x9c not deflate", "zlib")])
    with pytest.raises(RuntimeError, match="snapshot 3 of j-x is damaged"):
        Job(c, "j-x")._snapshot_bytes(3)
    c.close()


def _vtp_array(text, name):
    """The numbers of a .vtp DataArray, by its Name."""
    start = text.index(f'Name="{name}"')
    body = text[text.index(">", start) + 1:text.index("</DataArray>", start)]
    return [float(v) for v in body.split()]


def test_wait_follows_the_stream_watch_yields_the_samples_snapshot_gives_arrays(client, tmp_path,
                                                                              monkeypatch):
    # wait() and Sweep.wait() follow WatchJob instead of polling GetJob;
    # watch() yields the samples as they arrive; snapshot(i) is the mesh as numpy arrays.
    from activefoam.client import Job

    def no_polling(self):
        raise AssertionError("wait() polled GetJob")

    job = client.submit(dict(TINY, duration_s=20))
    live = []
    for row in job.watch():  # from the first sample, while the job runs
        live.append(row)
    assert [r["t_s"] for r in live] == [float(t) for t in range(21)]
    monkeypatch.setattr(Job, "info", no_polling)
    assert job.wait(timeout_s=120) == "succeeded"
    monkeypatch.undo()
    pd.testing.assert_frame_equal(pd.DataFrame(list(job.watch())), job.samples())
    sw = client.sweep(dict(TINY, snapshot_every_s=0), grid={"cells.gamma": [0.4, 0.6]}, seeds=[1])
    monkeypatch.setattr(Job, "info", no_polling)
    assert sw.wait(timeout_s=120) == {"succeeded": 2}
    monkeypatch.undo()

    job.export(tmp_path / "vtk")
    text = (tmp_path / "vtk" / "snap_000001.vtp").read_text()
    snap = job.snapshot(1)
    assert snap["t_s"] == 5.0 and snap["tri"].shape == (80, 3)
    assert snap["x"].ravel().tolist() == _vtp_array(text, "Points")
    assert snap["tri"].ravel().tolist() == _vtp_array(text, "connectivity")
    assert snap["cell"].tolist() == [0] * len(snap["x"])
    assert job.snapshot()["t_s"] == 20.0  # the latest


def _frames(path) -> int:
    import subprocess
    r = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0",
                        "-show_entries", "stream=nb_read_frames", "-of", "csv=p=0", str(path)],
                       capture_output=True, text=True, check=True)
    return int(r.stdout.strip())


def test_movie_runs_foam_export_movie_one_frame_a_snapshot(client, tmp_path):
    # Job.movie is `foam export --movie` (the CLI's renderer, Debian's ffmpeg).
    import shutil
    if not os.environ.get("FOAM_EXE"):
        pytest.skip("FOAM_EXE does not name a built foam (ctest sets it)")
    if not (shutil.which("ffmpeg") and shutil.which("ffprobe")):
        pytest.skip("ffmpeg/ffprobe missing (apt-get install ffmpeg)")
    job = client.submit(dict(TINY, duration_s=10))
    assert job.wait(timeout_s=120) == "succeeded"
    snaps = len(job.results_message(False).snapshots)
    assert snaps == 3
    out = job.movie(tmp_path / "cell.mp4", size=(320, 240))
    assert out == tmp_path / "cell.mp4" and out.stat().st_size > 0
    assert _frames(out) == snaps
    assert _frames(job.movie(tmp_path / "cell.gif", size=(160, 120), color="pressure")) == snaps
    none = client.submit(dict(TINY, snapshot_every_s=0))
    assert none.wait(timeout_s=120) == "succeeded"
    with pytest.raises(LookupError, match="no snapshots"):
        none.movie(tmp_path / "none.mp4")
    assert not (tmp_path / "none.mp4").exists()
    with pytest.raises(ValueError, match="mp4 or .gif"):
        job.movie(tmp_path / "cell.avi")
