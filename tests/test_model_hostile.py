"""Damaged or foreign checkpoints and bad model-command arguments: one line, never a traceback."""

from __future__ import annotations

import json
import pickle
import shutil

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from tests.test_model_core import trained_run

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("hostile")
    split, run = trained_run(tmp, 2)
    obj = tmp / "obj.png"
    cv2.imwrite(str(obj), np.full((40, 40, 3), 200, np.uint8))
    return split, run, obj


def _copy(run, tmp_path):
    dst = tmp_path / "copy"
    shutil.copytree(run, dst)
    return dst, dst / "checkpoint"


def _generate(run, obj, out):
    from cli.model_app import generate_app

    return CliRunner().invoke(
        generate_app,
        ["--checkpoint", str(run), "--object", str(obj), "--wrench", "0,0,2,0,0,0", "--out", str(out), "--steps", "2"],
    )


def _one_line_error(result, *needles):
    assert result.exit_code == 1, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    assert "Traceback" not in result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    for needle in needles:
        assert needle in lines[0], lines[0]


@pytest.mark.parametrize(
    "content",
    [b"", b"\x00\x01garbage" * 40, pickle.dumps({"weight": [1, 2, 3]})],
    ids=["empty", "random-bytes", "pickle"],
)
def test_damaged_weights_are_named(run, tmp_path, content):
    _, trained, obj = run
    copy, ck = _copy(trained, tmp_path)
    (ck / "ema.safetensors").write_bytes(content)
    _one_line_error(_generate(copy, obj, tmp_path / "f.png"), "ema.safetensors", "not a safetensors file")
    assert not (tmp_path / "f.png").exists()


@pytest.mark.parametrize(
    "edit,needle",
    [
        (lambda m: m["model"].update(unknown_knob=3), "unknown key(s) 'unknown_knob'"),
        (lambda m: m.update(step=-1), "[step]"),
        (lambda m: m.update(wrench_std=[0, 1, 1, 1, 1, 1]), "[wrench_std]"),
        (lambda m: m.update(mm_per_px="x"), "[mm_per_px]"),
        (lambda m: m["model"].update(conditioning="telepathy"), "conditioning must be one or more of"),
    ],
)
def test_state_json_is_checked_before_use(run, tmp_path, edit, needle):
    _, trained, obj = run
    copy, ck = _copy(trained, tmp_path)
    meta = json.loads((ck / "state.json").read_text())
    edit(meta)
    (ck / "state.json").write_text(json.dumps(meta))
    _one_line_error(_generate(copy, obj, tmp_path / "f.png"), "state.json", needle)


def test_state_json_that_is_not_json(run, tmp_path):
    _, trained, obj = run
    copy, ck = _copy(trained, tmp_path)
    (ck / "state.json").write_text("{not json")
    _one_line_error(_generate(copy, obj, tmp_path / "f.png"), "state.json", "not readable JSON")


def test_resume_from_a_damaged_optimizer_file_is_named(run, tmp_path):
    from model.denoiser.checkpoint import CheckpointError
    from model.denoiser.config import ModelConfig
    from model.training.build import build
    from model.training.trainer import TrainConfig

    split, trained, _ = run
    copy, ck = _copy(trained, tmp_path)
    (ck / "optimizer.safetensors").write_bytes(b"\xff" * 100)
    meta = json.loads((ck / "state.json").read_text())
    cfg = ModelConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in meta["model"].items()})
    trainer = build(cfg, TrainConfig(steps=4, batch_size=4), split, copy, log=lambda m: None)
    with pytest.raises(CheckpointError, match="optimizer.safetensors: not a safetensors file"):
        trainer.resume()


def test_generate_out_into_a_missing_folder_writes_the_frame(run, tmp_path):
    _, trained, obj = run
    out = tmp_path / "new" / "deeper" / "f.png"
    r = _generate(trained, obj, out)
    assert r.exit_code == 0, r.output
    assert cv2.imread(str(out)).shape == (16, 16, 3)


def test_generate_out_that_cannot_be_written_is_an_error(run, tmp_path):
    _, trained, obj = run
    _one_line_error(_generate(trained, obj, tmp_path / "frame.nonsense"), "--out", ".png")


def test_evaluate_on_a_missing_split_names_it(run, tmp_path):
    from cli.model_app import evaluate_app

    _, trained, _ = run
    r = CliRunner().invoke(
        evaluate_app,
        [
            "--checkpoint",
            str(trained),
            "--split",
            str(tmp_path / "nowhere"),
            "--out",
            str(tmp_path / "rep"),
            "--settings",
            "ddim:2",
            "--limit",
            "2",
        ],
    )
    _one_line_error(r, "nowhere")
    assert not (tmp_path / "rep").exists()


def test_generate_takes_a_library_object_or_a_run_file_and_a_size(run, tmp_path):
    from cli.model_app import generate_app

    split, trained, _ = run
    run_file = json.loads((split / "split.json").read_text())["runs"][0]["path"]
    for source in ("sphere10mm", run_file):
        r = CliRunner().invoke(
            generate_app,
            [
                "--checkpoint",
                str(trained),
                "--object",
                source,
                "--wrench",
                "0,0,2,0,0,0",
                "--out",
                str(tmp_path / "f.png"),
                "--steps",
                "2",
                "--size",
                "48",
                "--device",
                "cpu",
            ],
        )
        assert r.exit_code == 0, r.output
        assert "48x48 (upsampled from the model's 16x16)" in r.output
        assert cv2.imread(str(tmp_path / "f.png")).shape == (48, 48, 3)
    r = CliRunner().invoke(
        generate_app,
        [
            "--checkpoint",
            str(trained),
            "--object",
            "teapot",
            "--wrench",
            "0,0,2,0,0,0",
            "--out",
            str(tmp_path / "f.png"),
        ],
    )
    _one_line_error(r, "'teapot'", "sphere10mm")
    r = CliRunner().invoke(
        generate_app,
        [
            "--checkpoint",
            str(trained),
            "--object",
            "sphere10mm",
            "--wrench",
            "0,0,2,0,0,0",
            "--out",
            str(tmp_path / "f.png"),
            "--device",
            "tpu",
        ],
    )
    _one_line_error(r, "--device")
