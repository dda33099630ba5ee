"""The study tool's inputs and outputs under hostile or mistaken use: sizes counted before they
are built, files read to a cap, a base read from under the study's folder only, a token file
read as foam reads one, and a report that cannot be written ending in one line naming the file,
the older file left as it was. No foamd is needed."""

import errno
import os
import textwrap
import time

import pytest

from activefoam import study as st
from activefoam.study import outputs, verdicts
from test_study import _run, _synthetic

SPEC = 'scene = "fusion"\nduration_s = 60\n'


def _file(tmp, text, name="s.toml"):
    f = tmp / name
    f.write_text(textwrap.dedent(text))
    return f


def test_a_grid_is_counted_before_it_is_expanded(tmp_path):
    # Four 100-value axes in 2.6 KB: expanding the product first ended in a MemoryError.
    axes = "\n".join(f'"cells.k{k}" = [{", ".join(str(v) for v in range(100))}]'
                     for k in range(4))
    f = tmp_path / "big.toml"
    f.write_text(f'[study]\nname = "big"\nseeds = [1, 2]\n[spec]\nscene = "fusion"\n'
                 f'[[grid]]\n{axes}\n')
    assert f.stat().st_size < 2700
    t0 = time.monotonic()
    with pytest.raises(st.StudyError) as e:
        st.load(f)
    assert time.monotonic() - t0 < 0.5
    assert f"{f}: grid: 200000000 runs ([[grid]] products × 2 seeds), more than the 2000" \
        in str(e.value)
    r = _run(["check", str(f)], timeout=60)
    assert r.returncode == 2 and "200000000 runs" in r.stderr and "Traceback" not in r.stderr


def test_the_count_sums_the_grids_and_stops_early(tmp_path):
    assert st.studyfile.run_count([{"a": [1, 2]}, {"a": [3], "b": [1, 2, 3]}], 10) == 50
    # 60 axes of 100 values: counted in no time, said to be beyond 10^18.
    huge = [{f"k{k}": list(range(100)) for k in range(60)}]
    assert st.studyfile.run_count(huge, 1) == 10**18 + 1
    axes = "\n".join(f'"cells.k{k}" = [{", ".join(str(v) for v in range(100))}]'
                     for k in range(60))
    f = tmp_path / "huge.toml"
    f.write_text(f'[study]\nname = "h"\nseeds = [1]\n[spec]\nscene = "fusion"\n[[grid]]\n{axes}\n')
    with pytest.raises(st.StudyError, match="grid: more than 10\\^18 runs"):
        st.load(f)
    # Two grids of 1000 points each at 1 seed: 2000 runs, the most a study holds.
    f.write_text('[study]\nname = "h"\nseeds = [1]\n[spec]\nscene = "fusion"\n'
                 '[[grid]]\n"cells.alpha" = [' + ", ".join(map(str, range(1000))) + ']\n'
                 '[[grid]]\n"cells.gamma" = [' + ", ".join(map(str, range(1000))) + ']\n')
    assert len(st.load(f).runs()) == 2000


def test_a_study_file_is_read_to_its_cap(tmp_path):
    t0 = time.monotonic()
    with pytest.raises(st.StudyError, match="study: '/dev/zero' is not a regular file"):
        st.load("/dev/zero")
    big = tmp_path / "big.toml"
    big.write_text("# " + "x" * (1 << 20) + "\n")
    with pytest.raises(st.StudyError, match=f"study '{big}' holds {big.stat().st_size} bytes, "
                                            "more than the 1 MiB"):
        st.load(big)
    assert time.monotonic() - t0 < 1.0


def _with_base(tmp, base):
    return _file(tmp, f"""\
        [study]
        name = "b"
        base = "{base}"
        seeds = [1]
        [[grid]]
        "cells.alpha" = [0.5]
        """)


def test_a_base_is_read_from_under_the_study_files_folder_only(tmp_path):
    d = tmp_path / "study"
    d.mkdir()
    (d / "specs").mkdir()
    (d / "specs" / "base.toml").write_text(SPEC)
    (tmp_path / "outside.toml").write_text(SPEC)
    assert st.load(_with_base(d, "specs/base.toml")).base_text == SPEC
    # `..`, an absolute path, a symlink out of the folder: refused, naming the path and root.
    for base in ("../outside.toml", "/etc/passwd", "specs/../../outside.toml"):
        with pytest.raises(st.StudyError) as e:
            st.load(_with_base(d, base))
        assert "study.base: " in str(e.value) and f"is outside '{d}'" in str(e.value), base
    (d / "link.toml").symlink_to(tmp_path / "outside.toml")
    with pytest.raises(st.StudyError, match=f"'{tmp_path / 'outside.toml'}' is outside"):
        st.load(_with_base(d, "link.toml"))
    # Another root named: a base under it is read.
    s = st.load(_with_base(d, "../outside.toml"), base_root=tmp_path)
    assert s.base_text == SPEC
    f = _with_base(d, "../outside.toml")
    r = _run(["check", str(f)], timeout=60)
    assert r.returncode == 2 and "is outside" in r.stderr and "--base-root" in r.stderr
    r = _run(["--base-root", str(tmp_path), "check", str(f)], timeout=60)
    assert r.returncode == 0, r.stderr


def test_a_base_is_read_to_its_cap(tmp_path):
    big = tmp_path / "big.toml"
    with big.open("wb") as fh:  # 3 GB without the disk: sparse
        fh.truncate(3 << 30)
    t0 = time.monotonic()
    with pytest.raises(st.StudyError, match=f"study.base '{big}' holds {3 << 30} bytes, more "
                                            "than the 1 MiB"):
        st.load(_with_base(tmp_path, "big.toml"))
    assert time.monotonic() - t0 < 1.0
    (tmp_path / "latin1.toml").write_bytes(b'scene = "fusion"\n# \xe9\n')
    with pytest.raises(st.StudyError, match="study.base '.*latin1.toml' is not UTF-8 "
                                            "\\(byte 19\\)"):
        st.load(_with_base(tmp_path, "latin1.toml"))


def test_a_token_file_is_checked_before_anything_is_sent(tmp_path, monkeypatch):
    f = _with_base(tmp_path, "base.toml")
    (tmp_path / "base.toml").write_text(SPEC)
    monkeypatch.setenv("FOAM_SERVER", "127.0.0.1:1")  # nothing listens: nothing is sent
    for token_file, words in (("", "token file '': an empty path"),
                              ("/dev/zero", "token file '/dev/zero': not a readable file")):
        t0 = time.monotonic()
        r = _run(["--token-file", token_file, "run", str(f), "--no-wait"], timeout=60)
        assert r.returncode == 2 and words in r.stderr, r.stderr
        assert "Traceback" not in r.stderr and time.monotonic() - t0 < 30


def test_a_report_that_cannot_be_written_names_the_file_and_leaves_the_old_one(
        tmp_path, monkeypatch, capsys):
    f, d = _synthetic(tmp_path, shift_theta=0.5)
    assert st.main(["report", str(f), "--from-data", str(d), "--out", "/dev/full"]) == 2
    assert "error: --out: '/dev/full' is not a folder" in capsys.readouterr().err
    out = tmp_path / "out"
    assert st.main(["report", str(f), "--from-data", str(d), "--out", str(out)]) == 0
    png = out / "synthetic-curves.png"
    old = png.read_bytes()
    capsys.readouterr()

    import matplotlib.figure

    def full_disk(self, fname, **kw):  # the first bytes go out, then the disk is full
        with open(fname, "wb") as fh:
            fh.write(b"\x89PNG\r\n")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", full_disk)
    assert st.main(["report", str(f), "--from-data", str(d), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.strip() == f"error: {png}: No space left on device", err
    assert png.read_bytes() == old
    assert not [p for p in os.listdir(out) if p.startswith(".")], os.listdir(out)


def test_a_file_is_replaced_whole_or_not_at_all(tmp_path):
    target = tmp_path / "t.md"
    target.write_text("old")
    with pytest.raises(OSError) as e:
        with outputs.replacing(target) as tmp:
            tmp.write_text("half")
            raise OSError(errno.ENOSPC, "No space left on device")
    assert e.value.filename == str(target) and target.read_text() == "old"
    assert os.listdir(tmp_path) == ["t.md"]
    outputs.write_text(target, "new")
    assert target.read_text() == "new" and os.listdir(tmp_path) == ["t.md"]
    assert oct(target.stat().st_mode & 0o777) == oct(0o666 & ~outputs._umask())


def test_the_other_files_the_study_tool_reads_are_capped_and_named(tmp_path):
    big = tmp_path / "verdicts.toml"
    big.write_text("# " + "x" * (1 << 20) + "\n")
    with pytest.raises(st.StudyError, match=f"verdicts '{big}' holds .* more than the 1 MiB"):
        verdicts.load(big)
    f, d = _synthetic(tmp_path, shift_theta=0.5)
    (d / "collected.json").write_text("{not json")
    with pytest.raises(st.StudyError, match=f"--with-data: {d / 'collected.json'}: not JSON"):
        st.carried_runs(st.load(f), d)


def test_check_refuses_a_key_no_spec_has(tmp_path):
    # `check` passed a grid of cells.bogus, which `run` then had refused by foamd; likewise a
    # [spec] or [[diagnose]] key. Each is named with the closest key.
    head = '[study]\nname = "s"\nseeds = [1]\n[spec]\nscene = "fusion"\n'
    for rest, words in [
            ('[[grid]]\n"cells.gama" = [0.5, 0.6]\n',
             r"grid\[0\]\.cells\.gama: unknown spec key \(did you mean 'cells\.gamma'\?\)"),
            ('"numerics.dt" = 0.5\n[[grid]]\n"cells.alpha" = [0.5]\n',
             r"spec\.numerics\.dt: unknown spec key \(did you mean 'numerics\.dt_s'\?\)"),
            ('[[grid]]\n"cells.alpha" = [0.5]\n[[diagnose]]\nname = "d"\n'
             'spec = { "numerics.remesh_keepout_um" = 1.0 }\n',
             r"diagnose\[0\]\.spec\.numerics\.remesh_keepout_um: unknown spec key \(did you "
             r"mean 'numerics\.remesh_keep_out_um'\?\)")]:
        f = tmp_path / "s.toml"
        f.write_text(head + rest)
        with pytest.raises(st.StudyError, match=words):
            st.load(f)
    # The keys foam-run --keys lists, the scene's own, and the earlier switches foamd reads.
    keys = st.studyfile.spec_keys()
    for k in ("scene", "scene.kind", "seed", "cells.alpha", "numerics.remesh_keep_out_um",
              "scene.n_cells_a", "scene.axes_ratio", "accuracy.contact_angle_deg",
              "numerics.remesh_rescue"):
        assert k in keys, k
    assert "cells.bogus" not in keys and "cells" not in keys


def test_a_studys_spec_and_grids_take_the_prepare_table(tmp_path):
    # A controlled experiment: one aggregate prepared at the base point, every point run from it.
    # A [spec.prepare.cells] table and a dotted key in [spec] are one key foamd reads; a grid may
    # sweep one too; a misspelt one is named with the closest key.
    from activefoam.client import _spec_fields
    head = '[study]\nname = "s"\nseeds = [1]\n[spec]\nscene = "fusion"\n'
    grid = '[[grid]]\n"cells.l_eta_reduced" = [0.5, 2]\n'
    for rest in ('"prepare.cells.l_eta_reduced" = 0.5\n' + grid,
                 grid + '[spec.prepare.cells]\nl_eta_reduced = 0.5\n'):
        study = st.load(_file(tmp_path, head + rest))
        runs = study.runs()
        settings = [_spec_fields({}, study.settings(r))["settings"] for r in runs]
        assert ["prepare.cells.l_eta_reduced=0.5" in s for s in settings] == [True, True]
        assert [f"cells.l_eta_reduced={v}" in s for s, v in zip(settings, (0.5, 2))] == [True] * 2
    study = st.load(_file(tmp_path, head + '[[grid]]\n"prepare.cells.k_contact" = [50.0, 71.1]\n'))
    assert study.swept_keys() == ["prepare.cells.k_contact"]
    with pytest.raises(st.StudyError, match=r"spec\.prepare\.cells\.gama: unknown spec key "
                                            r"\(did you mean 'prepare\.cells\.gamma'\?\)"):
        st.load(_file(tmp_path, head + '"prepare.cells.gama" = 1.0\n' + grid))
