"""Root attributes carry a checksum: a relabelled or damaged text attribute is refused, never read.

HDF5 keeps variable-length text attributes in its global heap, which has no checksum: before, a
run's object name edited in place from sphere10mm to sphere15mm passed validate, info and split.
Files written before the checksum stay readable (validate notes it); the sensor kind must be one
of the known kinds (common/sensors.py).
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from test_verified_reads import one_error, write_run
from typer.testing import CliRunner

from acquisition import attr_checksum
from acquisition import schema as S
from acquisition.run_file import RunFileError, RunHeader, RunReader, RunWriter
from cli.dataset_app import app as dataset_app
from dataset.runs import check_run, validate
from protocols.plan import PHASES

runner = CliRunner()


def _relabel(path: Path, old: bytes, new: bytes) -> None:
    data = path.read_bytes()
    assert data.count(old) == 1 and len(old) == len(new)
    path.write_bytes(data.replace(old, new))


def test_an_object_name_relabelled_on_disk_is_refused_by_every_reader(tmp_path):
    path = write_run(tmp_path / "run.h5")
    _relabel(path, b"sphere10mm", b"sphere15mm")
    with h5py.File(path, "r") as f:  # HDF5 itself reads the new name without a word
        assert f.attrs[S.ATTR_OBJECT] == "sphere15mm"
    assert any(line.startswith("attribute attrs_sha256: the root attributes do not match") for line in validate(path))
    with pytest.raises(RunFileError, match=rf"^{path}: attribute attrs_sha256: the root attributes do not match"):
        RunReader.open(path)
    for args in (["info", str(path)], ["split", "8:2", str(path), "--out", str(tmp_path / "s")]):
        error = one_error(runner.invoke(dataset_app, args))
        assert f"{path}: attribute attrs_sha256" in error, error
    assert not (tmp_path / "s").exists()


def test_a_flipped_byte_in_the_sensor_kind_is_refused(tmp_path):
    path = write_run(tmp_path / "run.h5")
    data = bytearray(path.read_bytes())
    at = data.index(b"rgb\x00") if b"rgb\x00" in data else data.index(b"rgb")
    data[at + 2] ^= 0x01  # rgb -> rgc
    path.write_bytes(bytes(data))
    findings = validate(path)
    assert any(line.startswith("attribute sensor_kind: is 'rgc', expected one of rgb") for line in findings), findings
    with pytest.raises(RunFileError, match=f"{path}: malformed run file: attribute sensor_kind"):
        RunReader.open(path)


def test_files_written_before_the_checksum_stay_readable_and_validate_notes_it(tmp_path):
    path = write_run(tmp_path / "run.h5")
    with h5py.File(path, "r+") as f:
        del f.attrs[S.ATTR_ATTRS_SHA256]
    with RunReader.open(path) as run:
        assert run.n == 12 and any(note.startswith("no attribute checksum (written before") for note in run.notes)
    check = check_run(path)
    assert check.findings == [] and any(n.startswith("no attribute checksum (written before") for n in check.notes)
    result = runner.invoke(dataset_app, ["validate", str(path)])
    assert result.exit_code == 0 and f"{path}: note: no attribute checksum (written before" in result.output


def test_the_checksum_covers_every_attribute_exactly(tmp_path):
    """Any value of any root attribute changes it, a float's last bit and a list's order included;
    rewriting the same values does not."""
    path = write_run(tmp_path / "run.h5")
    with h5py.File(path, "r+") as f:
        sealed = f.attrs[S.ATTR_ATTRS_SHA256]
        assert attr_checksum.digest(f.attrs) == sealed
        f.attrs[S.ATTR_OBJECT] = "sphere10mm"  # the same value again
        assert attr_checksum.digest(f.attrs) == sealed
        mm = float(f.attrs[S.ATTR_MM_PER_PX])
        f.attrs[S.ATTR_MM_PER_PX] = np.nextafter(mm, 1.0)
        assert attr_checksum.digest(f.attrs) != sealed
        f.attrs[S.ATTR_MM_PER_PX] = mm
        f.attrs[S.ATTR_PHASES] = list(reversed(PHASES))
        assert attr_checksum.digest(f.attrs) != sealed
        f.attrs[S.ATTR_PHASES] = list(PHASES)
        f.attrs["an_attribute_added_later"] = "x"
        assert attr_checksum.digest(f.attrs) != sealed


def test_a_run_of_an_unknown_sensor_kind_is_never_written(tmp_path):
    header = RunHeader("t", "", "", "sphere10mm", "", "gelsight", 0.5, 1.0, 2, (0, 0, 0, 0), PHASES)
    image = np.zeros((16, 16, 3), np.uint8)
    with pytest.raises(RunFileError, match="sensor kind 'gelsight' is not one of rgb, rgb_markers, white_markers"):
        RunWriter.create(tmp_path / "run.h5", header, (16, 16, 3), image, image)
    assert list(tmp_path.iterdir()) == []
