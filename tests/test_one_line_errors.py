"""Damage no check expected, errors nothing caught and files that are not files: one line, never a hang.

Before: a damaged chunk index of the frames escaped ``verify_frames`` as a RuntimeError traceback
(the dataset app's ``friendly`` caught no RuntimeError), and ``dataset info fifo.h5`` waited for ever.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_verified_reads import chunk_index_byte, flip, one_error, write_run
from typer.testing import CliRunner

from acquisition import schema as S
from cli.dataset_app import app as dataset_app
from cli.model_app import generate_app
from cli.rig_app import app as rig_app
from dataset.runs import validate

runner = CliRunner()


def test_a_damaged_chunk_index_of_the_frames_is_one_line(tmp_path):
    path = write_run(tmp_path / "run.h5")
    flip(path, chunk_index_byte(path, S.FRAMES))
    error = one_error(runner.invoke(dataset_app, ["split", "8:2", str(path), "--out", str(tmp_path / "s")]))
    assert error.startswith(f"error: {path}: frames: chunk index unreadable ("), error
    assert "the file is damaged" in error
    findings = validate(path)  # one finding, not one failed (and slow) read per frame
    assert [f for f in findings if f.startswith("frames")] == [findings[0]], findings
    assert findings[0].startswith("frames: chunk index unreadable"), findings


def test_a_damaged_chunk_index_of_a_row_dataset_is_one_line(tmp_path):
    path = write_run(tmp_path / "run.h5")
    flip(path, chunk_index_byte(path, S.WRENCH))
    error = one_error(runner.invoke(dataset_app, ["info", str(path)]))
    assert f"{path}: wrench: chunk index unreadable" in error, error


def _boom(*args, **kwargs):
    raise ZeroDivisionError("nobody expected this")


@pytest.mark.parametrize("app", ["dataset", "model", "sensor"])
def test_an_unexpected_error_is_one_line_naming_its_type(tmp_path, monkeypatch, app):
    if app == "dataset":
        monkeypatch.setattr("dataset.runs.summarize", _boom)
        result = runner.invoke(dataset_app, ["info", str(tmp_path / "run.h5")])
    elif app == "model":
        monkeypatch.setattr("model.generation.inference.TrainedModel.load", _boom)
        args = ["--checkpoint", str(tmp_path), "--object", "sphere10mm", "--wrench", "0,0,1,0,0,0"]
        result = runner.invoke(generate_app, [*args, "--out", str(tmp_path / "x.png"), "--threads", "1"])
    else:
        monkeypatch.setattr("cli.sensor_inputs.from_folder", _boom)
        result = runner.invoke(rig_app, ["sensor", "calibrate", str(tmp_path), "--out", str(tmp_path / "p.toml")])
    assert one_error(result) == "error: ZeroDivisionError: nobody expected this"


def test_a_named_pipe_is_refused_at_once_never_read(tmp_path):
    """In its own process, under a deadline: before, opening the pipe waited for a writer for ever."""
    fifo = tmp_path / "fifo.h5"
    os.mkfifo(fifo)
    dataset = Path(sys.executable).parent / "dataset"
    for command in (["info", str(fifo)], ["validate", str(fifo)], ["split", "8:2", str(fifo), "--out", "s"]):
        proc = subprocess.run([str(dataset), *command], capture_output=True, text=True, timeout=60, cwd=tmp_path)
        text = proc.stdout + proc.stderr
        assert proc.returncode == 1 and "Traceback" not in text, text
        assert f"{fifo}: not a regular file" in text or f"{fifo}: file: not a regular file" in text, text
