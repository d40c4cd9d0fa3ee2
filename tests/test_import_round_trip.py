"""Export and import: what a run says about itself comes back, a refused import writes nothing.

Before: import wrote files that every reader then refused (t_frame_s not increasing), always wrote
status complete (an aborted run came back complete), export dropped the sensor profile, and a
SIGTERM'd import (or a failing close) left its temporary file and its locks behind.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from test_verified_reads import _import, _rows, _write_rows, folder, one_error, write_run  # noqa: F401 (fixture)
from typer.testing import CliRunner

from acquisition import schema as S
from acquisition.run_file import RunReader, RunWriter
from cli.dataset_app import app as dataset_app
from dataset.interchange import export_run
from sensor_sim.profile import default_profile

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


def _leftovers(tmp_path: Path, name: str) -> list[str]:
    return sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(name))


@pytest.mark.parametrize("column", [S.T_FRAME, S.T_CAPTURE])
def test_rows_every_reader_would_refuse_are_refused_naming_the_csv_row(folder, tmp_path, column):  # noqa: F811
    header, rows = _rows(folder)
    at = header.index(column)
    rows[6][at] = rows[5][at]  # CSV row 8 (the header is row 1) repeats row 7's time
    _write_rows(folder, header, rows)
    out = tmp_path / "out.h5"
    error = one_error(_import(folder, out))
    assert f"frames.csv: {column}: not increasing at row 8" in error, error
    assert _leftovers(tmp_path, "out.h5") == []


def _aborted(path: Path) -> Path:
    """A run stopped after 12 of its 20 planned frames, with its reason."""
    write_run(path, n=20, written=12, close=False)
    w = RunWriter.reopen(path)
    w.set_status("aborted", "force limit: Fz = 9 N")
    w.close()
    return path


def test_status_reason_planned_frames_and_profile_come_back(tmp_path):
    src = _aborted(tmp_path / "src.h5")
    export_run(src, tmp_path / "folder")
    meta = json.loads((tmp_path / "folder" / "run.json").read_text())
    assert (meta["status"], meta["reason"], meta["frames_planned"]) == ("aborted", "force limit: Fz = 9 N", 20)
    assert meta["sensor_profile"] == default_profile().record()
    result = runner.invoke(dataset_app, ["import", str(tmp_path / "folder"), "--out", str(tmp_path / "back.h5")])
    assert result.exit_code == 0, result.output
    with RunReader.open(tmp_path / "back.h5") as back, RunReader.open(src) as orig:
        assert (back.status, back.reason) == ("aborted", "force limit: Fz = 9 N")
        assert back.number(S.ATTR_FRAMES_PLANNED) == 20 and back.n == 12
        assert back.sensor_profile == orig.sensor_profile != ""
        assert back.text(S.ATTR_OBJECT_GEOMETRY) == orig.text(S.ATTR_OBJECT_GEOMETRY)
    split = runner.invoke(dataset_app, ["split", "8:2", str(tmp_path / "back.h5"), "--out", str(tmp_path / "s")])
    assert split.exit_code == 1 and "run is aborted (force limit: Fz = 9 N), 12/20 frames" in split.output


def test_a_run_exported_while_running_stays_incomplete(tmp_path):
    src = write_run(tmp_path / "src.h5", n=20, written=12, close=False)  # as a crash leaves it
    export_run(src, tmp_path / "folder")
    assert json.loads((tmp_path / "folder" / "run.json").read_text())["status"] == "running"
    result = runner.invoke(dataset_app, ["import", str(tmp_path / "folder"), "--out", str(tmp_path / "back.h5")])
    assert result.exit_code == 0, result.output
    with RunReader.open(tmp_path / "back.h5") as back:
        assert back.status == "aborted" and "run.json says running" in back.reason, back.reason


def test_run_json_values_are_checked(folder, tmp_path):  # noqa: F811
    meta_path = folder / "run.json"
    good = json.loads(meta_path.read_text())
    for key, value, words in (
        ("status", "finished", "[status] must be one of running, complete, aborted, interrupted, got 'finished'"),
        ("frames_planned", 2.5, "[frames_planned] must be a whole number"),
        ("frames_planned", 3, "[frames_planned] is 3, fewer than the 20 rows of frames.csv"),
        ("sensor_profile", "name = 1", "[sensor_profile]"),
    ):
        meta_path.write_text(json.dumps(good | {key: value}))
        error = one_error(_import(folder, tmp_path / "x.h5"))
        assert f"{meta_path}: " in error and words in error, error
        assert _leftovers(tmp_path, "x.h5") == []


def test_a_profile_given_against_the_exported_one_is_refused_naming_both(folder, tmp_path):  # noqa: F811
    shipped = Path(default_profile().path)
    other = tmp_path / "other.toml"  # the shipped profile under another name: another content hash
    shutil.copy(shipped.with_suffix(".png"), tmp_path / shipped.with_suffix(".png").name)
    other.write_text(shipped.read_text().replace('name = "gelsight_mini"', 'name = "other_mini"'))
    error = one_error(_import(folder, tmp_path / "x.h5", "--profile", str(other)))
    assert "[sensor_profile] is gelsight_mini" in error and "--profile gives other_mini" in error, error
    same = _import(folder, tmp_path / "y.h5", "--profile", str(default_profile().path))
    assert same.exit_code == 0, same.output


SIGTERM_IMPORT = """
import os, signal, sys
from acquisition.run_writer import RunWriter
from cli.dataset_app import app

append = RunWriter.append
def append_then_terminated(self, frame, stream=None, **row):
    append(self, frame, stream, **row)
    if self.n == 5:  # half-way through the import
        os.kill(os.getpid(), signal.SIGTERM)
RunWriter.append = append_then_terminated
app(["import", sys.argv[1], "--out", sys.argv[2]])
"""


def test_a_sigterm_during_an_import_leaves_nothing_behind(folder, tmp_path):  # noqa: F811
    out = tmp_path / "out.h5"
    proc = subprocess.run(
        [sys.executable, "-c", SIGTERM_IMPORT, str(folder), str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert proc.returncode == 128 + signal.SIGTERM, proc.stdout + proc.stderr
    assert "interrupted (SIGTERM)" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    assert _leftovers(tmp_path, "out.h5") == []


def test_a_failing_close_still_removes_the_temporary_file(folder, tmp_path, monkeypatch):  # noqa: F811
    """A refused import whose writer then fails to close: before, the close's error skipped the unlink."""
    (folder / "frames" / "000010.png").unlink()
    opened = []

    def failing_close(self):
        opened.append(self.f)
        from acquisition.run_file import RunFileError

        raise RunFileError(f"{self.path}: closing failed (No space left on device)")

    monkeypatch.setattr(RunWriter, "close", failing_close)
    error = one_error(_import(folder, tmp_path / "out.h5"))
    assert "000010.png" in error, error
    for f in opened:
        f.close()
    assert _leftovers(tmp_path, "out.h5") == [], os.listdir(tmp_path)
