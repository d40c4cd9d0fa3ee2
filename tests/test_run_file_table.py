"""The run-file field table (acquisition/schema.py) is the one list of per-frame fields:
a row added there is written, validated, exported, imported, merged and served for
training with no other change; phases decode through the file's own attribute."""

import csv
import json

import h5py
import numpy as np
import pytest

from acquisition import schema as S
from acquisition.run_file import RunFileError, RunHeader, RunWriter, open_for_reading
from acquisition.run_layout import decode_phases
from dataset.interchange import export_run, import_run
from dataset.merge import merge_runs
from dataset.runs import check_run

AREA = S.Field("contact_area_mm2", (), "f8", "mm²", True, required=False, fill=-1.0)
SHIFT = S.Field("marker_shift_px", (2,), "f4", "px, px", True, required=False)
PHASES = ("approach", "press", "shear", "return", "twist", "untwist", "retract")


@pytest.fixture
def wider_table(monkeypatch):
    """The table with two fields added, as a developer adding a field would (one row each)."""
    monkeypatch.setattr(S, "PER_FRAME_FIELDS", (*S.PER_FRAME_FIELDS, AREA, SHIFT))
    monkeypatch.setattr(S, "FIELDS", (*S.FIELDS, AREA, SHIFT))


def frame(i: int, size: int = 16) -> np.ndarray:
    return np.random.default_rng(i).integers(20, 230, (size, size, 3), dtype=np.uint8)


def write_run(path, n=6, *, phases=PHASES, phase="press", extra=lambda i: {}):
    header = RunHeader("test", "# x", "", "sphere10mm", "", "rgb", 0.5, 1.0, n, (0, 0, 0, 0), phases)
    w = RunWriter.create(path, header, (16, 16, 3), frame(99), frame(98))
    for i in range(n):
        row = S.blank_row() | {
            S.WRENCH: np.full(6, 0.25 * i),
            S.T_FRAME: float(i),
            S.T_CAPTURE: float(i),
            S.CAPTURE_INDEX: i,
            S.PHASE_INDEX: phases.index(phase),
            S.LEVEL: 1,
        }
        w.append(frame(i), **(row | extra(i)))
    w.set_status("complete", "")
    w.close()
    return path


def values(i):
    return {AREA.path: 1.5 * i, SHIFT.path: np.array([i, -i], dtype="f4")}


def test_an_added_field_is_written_validated_exported_imported_and_merged(wider_table, tmp_path):
    src = write_run(tmp_path / "src.h5", extra=values)
    with open_for_reading(src) as f:
        np.testing.assert_array_equal(f[AREA.path][:], 1.5 * np.arange(6))
        assert f[SHIFT.path].shape == (6, 2) and f[SHIFT.path].dtype == np.float32
        assert f[AREA.path].attrs["units"] == "mm²"
    assert check_run(src).findings == []

    export_run(src, tmp_path / "folder")
    with open(tmp_path / "folder" / "frames.csv", newline="") as fh:
        header = next(csv.reader(fh))
    assert {"contact_area_mm2", "marker_shift_px_0", "marker_shift_px_1"} <= set(header)
    import_run(tmp_path / "folder", tmp_path / "back.h5")
    merge_runs([src, tmp_path / "back.h5"], tmp_path / "merged.h5")
    assert check_run(tmp_path / "back.h5").findings == []  # (a merge keeps each source's times: not validated)
    for path, n in ((tmp_path / "back.h5", 6), (tmp_path / "merged.h5", 12)):
        with open_for_reading(path) as f:
            np.testing.assert_array_equal(f[AREA.path][:], np.tile(1.5 * np.arange(6), n // 6))
            np.testing.assert_array_equal(f[SHIFT.path][:6, 0], np.arange(6))

    # validate checks the new field like every other row
    with h5py.File(src, "r+") as f:
        f[AREA.path][2] = np.nan
    assert any(line.startswith("contact_area_mm2: NaN/inf in 1 rows") for line in check_run(src).findings)


def test_a_row_must_name_every_field_and_only_fields_of_the_table(wider_table, tmp_path):
    header = RunHeader("test", "# x", "", "sphere10mm", "", "rgb", 0.5, 1.0, 2, (0, 0, 0, 0), PHASES)
    w = RunWriter.create(tmp_path / "r.h5", header, (16, 16, 3), frame(0), frame(0))
    try:
        without = {k: v for k, v in S.blank_row().items() if k not in (AREA.path, SHIFT.path)}
        with pytest.raises(RunFileError, match="frame 0 has no contact_area_mm2, marker_shift_px"):
            w.append(frame(0), **without)
        with pytest.raises(RunFileError, match="contact_aera_mm2 not in the run-file field table"):
            w.append(frame(0), **S.blank_row() | values(0) | {"contact_aera_mm2": 1.0})
    finally:
        w.close()


def test_files_written_before_the_field_stay_valid_and_get_its_fill(tmp_path, monkeypatch):
    old = write_run(tmp_path / "old.h5")  # the table as it is today
    monkeypatch.setattr(S, "PER_FRAME_FIELDS", (*S.PER_FRAME_FIELDS, AREA, SHIFT))
    monkeypatch.setattr(S, "FIELDS", (*S.FIELDS, AREA, SHIFT))
    assert check_run(old).findings == []
    export_run(old, tmp_path / "folder")  # no columns for the fields it lacks...
    import_run(tmp_path / "folder", tmp_path / "back.h5")  # ...so import fills them
    merge_runs([old, tmp_path / "back.h5"], tmp_path / "merged.h5")
    with open_for_reading(tmp_path / "merged.h5") as f:
        np.testing.assert_array_equal(f[AREA.path][:], np.full(12, -1.0))
    w = RunWriter.reopen(old)  # appending to an old file: the fields it has, no more
    try:
        w.append(frame(7), **S.blank_row() | {S.CAPTURE_INDEX: 6, S.T_FRAME: 6.0, S.T_CAPTURE: 6.0})
    finally:
        w.close()


def test_phases_decode_through_the_files_own_attribute(tmp_path):
    other_order = tuple(reversed(PHASES))  # a file from another version, phases in another order
    src = write_run(tmp_path / "src.h5", phases=other_order, phase="shear")
    std = write_run(tmp_path / "std.h5", phase="twist")
    with open_for_reading(src) as f:
        assert decode_phases(f) == other_order and set(f[S.PHASE_INDEX][:]) == {other_order.index("shear")}
    export_run(src, tmp_path / "folder")
    with open(tmp_path / "folder" / "frames.csv", newline="") as fh:
        assert {row["phase"] for row in csv.DictReader(fh)} == {"shear"}
    assert json.loads((tmp_path / "folder" / "run.json").read_text())["phases"] == list(other_order)
    import_run(tmp_path / "folder", tmp_path / "back.h5")
    merge_runs([src, std], tmp_path / "merged.h5")
    expected = {tmp_path / "back.h5": ["shear"] * 6, tmp_path / "merged.h5": ["shear"] * 6 + ["twist"] * 6}
    for path, expect in expected.items():
        with open_for_reading(path) as f:
            names = decode_phases(f)
            assert [names[i] for i in f[S.PHASE_INDEX][:]] == expect, path
    w = RunWriter.reopen(src)  # a resumed run encodes through the file's list, not the code's
    try:
        assert w.phase_index("press") == other_order.index("press") != PHASES.index("press")
        with pytest.raises(RunFileError, match="phase 'stroke' is not in the file's phases"):
            w.phase_index("stroke")
    finally:
        w.close()
