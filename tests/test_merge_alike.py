"""Merge keeps one reference frame and one object, so it merges only runs that share them; and it reads
each frame once.

Before: merge kept the first source's reference frame whatever the others' were and never compared
``object_geometry``; merge, export and compact verified every frame's checksum and then read every
frame again through HDF5 (which checks the same checksum), and compact did so before finding a file
compressed already.
"""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from test_verified_reads import chunk_middle, flip, one_error, write_run
from typer.testing import CliRunner

from acquisition import attr_checksum
from acquisition import schema as S
from acquisition.run_file import RunReader
from cli.dataset_app import app as dataset_app
from dataset.merge import REFERENCE_TOLERANCE
from dataset.runs import validate

runner = CliRunner()


def _set_reference(path, change) -> None:
    with h5py.File(path, "r+") as f:
        ref = f[S.REFERENCE_FRAME][()].astype(float)
        f[S.REFERENCE_FRAME][...] = np.clip(np.round(change(ref)), 0, 255).astype(np.uint8)


def test_reference_frames_alike_up_to_sensor_noise_merge_and_the_difference_is_recorded(tmp_path):
    a, b = write_run(tmp_path / "a.h5"), write_run(tmp_path / "b.h5", seed=1)
    rng = np.random.default_rng(5)
    _set_reference(b, lambda ref: ref + rng.normal(0, 2.0, ref.shape))  # the same sensor, another moment
    out = tmp_path / "ab.h5"
    result = runner.invoke(dataset_app, ["merge", str(a), str(b), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert validate(out) == []
    with RunReader.open(out) as m:
        line = [x for x in m.text(S.ATTR_RIG_CONFIG).splitlines() if x.startswith(str(b.resolve()))][0]
        gap = float(line.split("reference frame within ")[1].split()[0])
        assert 0 < gap < REFERENCE_TOLERANCE, line


def test_a_reference_frame_of_another_sensor_or_with_a_contact_is_refused(tmp_path):
    a = write_run(tmp_path / "a.h5")
    for name, change in (
        ("lit.h5", lambda ref: ref * 1.15),  # another sensor's light, or another gel
        ("pressed.h5", lambda ref: ref + 30 * (np.hypot(*np.mgrid[-16:16, -16:16]) < 6)[..., None]),
    ):
        b = write_run(tmp_path / name, seed=1)
        _set_reference(b, change)
        out = tmp_path / "ab.h5"
        error = one_error(runner.invoke(dataset_app, ["merge", str(a), str(b), "--out", str(out)]))
        assert f"{b}: its reference_frame differs from {a}'s by up to" in error and "grey levels" in error, error
        assert not list(tmp_path.glob("ab.h5*"))


def test_another_object_geometry_is_refused(tmp_path):
    a, b = write_run(tmp_path / "a.h5"), write_run(tmp_path / "b.h5", seed=1)
    with h5py.File(b, "r+") as f:  # a run written with another description of the indenter
        f.attrs[S.ATTR_OBJECT_GEOMETRY] = "sphere, 12 mm"
        attr_checksum.seal(f)
    error = one_error(runner.invoke(dataset_app, ["merge", str(a), str(b), "--out", str(tmp_path / "ab.h5")]))
    assert "runs differ in object_geometry" in error and "'sphere, 12 mm'" in error, error


def _no_second_pass(monkeypatch) -> None:
    def refuse(self):
        raise AssertionError("a separate verification pass over every frame")

    monkeypatch.setattr(RunReader, "verify_frames", refuse)


def test_merge_and_export_read_each_frame_once_and_still_name_a_damaged_one(tmp_path, monkeypatch):
    _no_second_pass(monkeypatch)
    a, b = write_run(tmp_path / "a.h5"), write_run(tmp_path / "b.h5", seed=1)
    assert runner.invoke(dataset_app, ["merge", str(a), str(b), "--out", str(tmp_path / "ab.h5")]).exit_code == 0
    assert runner.invoke(dataset_app, ["export", str(a), "--out", str(tmp_path / "x")]).exit_code == 0
    flip(b, chunk_middle(b, S.FRAMES, 7))
    error = one_error(runner.invoke(dataset_app, ["merge", str(a), str(b), "--out", str(tmp_path / "ab2.h5")]))
    assert f"{b}: frames[7]: checksum mismatch" in error, error
    error = one_error(runner.invoke(dataset_app, ["export", str(b), "--out", str(tmp_path / "y")]))
    assert f"{b}: frames[7]: checksum mismatch" in error, error
    assert not list(tmp_path.glob("ab2.h5*")) and not (tmp_path / "y").exists()
    assert not [p for p in tmp_path.iterdir() if ".exporting-" in p.name]


def test_compact_reads_no_frame_of_a_file_compressed_already(tmp_path, monkeypatch):
    _no_second_pass(monkeypatch)
    path = write_run(tmp_path / "run.h5")

    def no_frame(self, i):
        raise AssertionError(f"frame {i} read")

    monkeypatch.setattr(RunReader, "frame", no_frame)
    result = runner.invoke(dataset_app, ["compact", str(path)])
    assert result.exit_code == 0 and "frames already compressed; unchanged" in result.output, result.output


@pytest.mark.parametrize("damage", ["flip", "cut"])
def test_compact_of_an_uncompressed_file_names_a_damaged_frame_from_its_copy_read(tmp_path, monkeypatch, damage):
    from test_storage import write_run as write_plain

    _no_second_pass(monkeypatch)
    path = write_plain(tmp_path / "run.h5", compress=False)
    before = path.read_bytes()
    if damage == "flip":
        flip(path, chunk_middle(path, S.FRAMES, 5))
        words = f"{path}: frames[5]: checksum mismatch"
    else:
        path.write_bytes(before[:-1000])
        words = f"{path}: truncated"
    error = one_error(runner.invoke(dataset_app, ["compact", str(path)]))
    assert words in error, error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]
