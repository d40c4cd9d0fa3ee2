"""Held-out objects: `dataset split --hold-out` and one evaluation report with a section per test part."""

import json
import re

import numpy as np
import pytest

from tests.test_model_core import SMALL, write_run

SIZE = 16


def press_run(path, obj, n=30, seed=0):
    """A small run of a library object: a press at the centre (z deeper, Fz larger, every third frame
    back at the same depths), random frames; enough to split, train on and sweep."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        depth = 0.05 * (i % 10)
        frame = rng.integers(0, 256, (SIZE, SIZE, 3), dtype=np.uint8)
        wrench = np.array([0.1 * rng.normal(), 0.1 * rng.normal(), 0.3 + 4 * depth, 0, 0, 0.01 * rng.normal()])
        rows.append((frame, wrench, np.zeros(4), np.array([0.0, 0.0, -depth, 0.0])))
    return write_run(path, obj, rows, reference=np.full((SIZE, SIZE, 3), 128, np.uint8))


@pytest.fixture
def runs(tmp_path):
    return [
        press_run(tmp_path / "sphere10mm.h5", "sphere10mm"),
        press_run(tmp_path / "square.h5", "square", seed=1),
        press_run(tmp_path / "heart.h5", "heart", seed=2),
    ]


def test_hold_out_gives_a_test_object_part_and_names_the_objects(runs, tmp_path):
    from dataset.split import SplitError, load_split, make_split

    s = make_split(runs, "8:2", tmp_path / "s", hold_out=["heart"])
    manifest, parts = load_split(tmp_path / "s")
    assert set(parts) == {"train", "test", "test_object"}
    assert manifest["held_out_objects"] == ["heart"]
    assert manifest["objects"] == {
        "train": ["sphere10mm", "square"],
        "test": ["sphere10mm", "square"],
        "test_object": ["heart"],
    }
    assert len(parts["test_object"]) == 30 and set(parts["test_object"][:, 0]) == {2}
    assert len(parts["train"]) == 48 and len(parts["test"]) == 12  # 8:2 of the other 60 frames
    # the training statistics come from the training objects only: heart's frames are not in them
    assert s.wrench_mean[2] == pytest.approx(0.3 + 4 * 0.05 * 4.5, abs=0.3)
    assert manifest["wrench_percentiles"]["p98"][2] > manifest["wrench_percentiles"]["p2"][2]
    with pytest.raises(SplitError, match="no run of that object; the runs hold heart, sphere10mm, square"):
        make_split(runs, "8:2", tmp_path / "t", hold_out=["ring"])
    with pytest.raises(SplitError, match="that is every object"):
        make_split(runs, "8:2", tmp_path / "t", hold_out=["heart", "square", "sphere10mm"])
    with pytest.raises(SplitError, match="with --by object"):
        make_split(runs, "8:2", tmp_path / "t", hold_out=["heart"], by="object")


def test_split_command_hold_out(runs, tmp_path):
    from typer.testing import CliRunner

    from cli.dataset_app import app

    r = CliRunner().invoke(app, ["split", "8:2", *map(str, runs), "--out", str(tmp_path / "s"), "--hold-out", "heart"])
    assert r.exit_code == 0, r.output
    assert "test_object 30" in r.output and "held out (test_object): heart" in r.output
    r = CliRunner().invoke(app, ["split", "8:2", *map(str, runs), "--out", str(tmp_path / "t"), "--hold-out", "pear"])
    assert r.exit_code == 1 and "--hold-out pear: no run of that object" in r.output and "Traceback" not in r.output


def test_evaluate_on_an_object_split_writes_one_report_with_both_parts(runs, tmp_path):
    from typer.testing import CliRunner

    from cli.model_app import evaluate_app
    from dataset.split import make_split

    make_split(runs, "8:2", tmp_path / "s", hold_out=["heart"])
    run = _train(tmp_path / "s", tmp_path / "run")
    r = CliRunner().invoke(
        evaluate_app,
        [
            *("--checkpoint", str(run), "--split", str(tmp_path / "s"), "--out", str(tmp_path / "rep")),
            *("--settings", "ddim:2", "--limit", "3", "--sweep-poses", "1", "--sweep-points", "3"),
        ],
    )
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    # progress of both parts' sampling and of the force sweep, with the time left
    assert any(line.startswith("test_object: ddim 2 steps: 3/3 frames, ") for line in lines), r.output
    assert any(line.startswith("test: force sweep: Fz at pose 1/1: 1/4 sweeps, ") and "left" in line for line in lines)
    text = (tmp_path / "rep" / "report.md").read_text()
    assert "held out of training (part test_object): heart" in text and "trained on: sphere10mm, square" in text
    assert "## Part `test`: unseen frames of the training objects (sphere10mm, square)" in text
    assert "## Part `test_object`: objects held out of training, never seen by the model (heart)" in text
    # each part: the whole-frame table, the near-contact table and the light-load table (issue 37)
    assert text.count("| this model (ddim, 2 steps) |") == 6 and text.count("### Near the contact") == 2
    assert text.count("**Light load**: the 3 frame(s) of smallest Fz") == 2
    assert "**Verdict near the contact**" in text and "within 3 mm of the contact the real frame shows" in text
    assert text.count("### Force response") == 2 and "| Fz | " in text and "| Mz | " in text
    for png in ("samples.png", "samples-test_object.png", "force_sweep_Fz.png", "force_sweep_Fx-test_object.png"):
        assert (tmp_path / "rep" / png).stat().st_size > 1000, png
    saved = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert set(saved["parts"]) == {"test", "test_object"} and saved["parts"]["test_object"]["objects"] == ["heart"]
    fz = [s for s in saved["parts"]["test_object"]["force_sweep"] if s["component"] == "Fz"]
    # three values within the training range, two past its maximum (no reference there)
    assert len(fz) == 1 and len(fz[0]["values"]) == 5 and fz[0]["inside_training_range"] == [True] * 3 + [False] * 2
    # the pose frames sit at x = y = 0 where the run has frames at several depths: references are found
    assert fz[0]["references_real"] + fz[0]["references_render"] >= 1 and any(
        src.startswith(("real frame", "physics render")) for src in fz[0]["sources"]
    )
    # every part's table has the baselines that need no model, beside the physics render, each with an interval
    for name in (
        "baseline: background (the run's no-contact frame)",
        "baseline: mean training frame",
        "baseline: background + mean training contact at the pose",
        "baseline: nearest training frame by condition",
        "baseline: physics render at the measured pose",
    ):
        assert text.count(f"| {name}") == 6, name  # whole frame, near the contact, light load; two parts
    assert text.count("**Verdict**: ") >= 4  # the metrics and the force response of each part
    row = next(line for line in text.splitlines() if line.startswith("| baseline: mean training frame |"))
    assert re.search(r"\| \d+\.\d\d \(\d+\.\d\d–\d+\.\d\d\) \|", row), row  # MSE (95 % interval)
    assert len(saved["parts"]["test"]["baselines"]) == 4 and saved["parts"]["test"]["baselines"][0]["ci"]["mse"]
    # the paper's rows in a table of their own, labelled; no path of this machine anywhere
    paper = text.split("## The paper's numbers")[1]
    assert "256×256 px" in paper and "| paper, RGB light | 21.0 |" in paper
    assert "paper, RGB light" not in text.split("## The paper's numbers")[0]
    assert str(tmp_path) not in text and str(tmp_path) not in (tmp_path / "rep" / "metrics.json").read_text()
    # one part asked for: the old single-section report
    r = CliRunner().invoke(
        evaluate_app,
        [
            *("--checkpoint", str(run), "--split", str(tmp_path / "s"), "--out", str(tmp_path / "one")),
            *("--settings", "ddim:2", "--limit", "2", "--part", "test", "--no-force-sweep", "--no-baseline"),
        ],
    )
    assert r.exit_code == 0, r.output
    text = (tmp_path / "one" / "report.md").read_text()
    assert "test_object" not in text.split("- **split**")[0] and "No force sweep: not asked for" in text


def _train(split, out):
    from model.training.build import build
    from model.training.trainer import TrainConfig

    trainer = build(SMALL, TrainConfig(steps=2, batch_size=4, checkpoint_every=100), split, out, log=lambda m: None)
    trainer.train()
    trainer.save()
    return out


def test_sweep_range_of_a_split_written_before_the_percentiles(runs, tmp_path):
    """A split.json without wrench_percentiles: the range comes from the training part's frames."""
    from dataset.split import PERCENTILES, make_split
    from dataset.torch_dataset import TactileDataset
    from model.sweeps.evaluate_sweep import _train_percentiles

    make_split(runs, "8:2", tmp_path / "s", hold_out=["heart"])
    manifest = json.loads((tmp_path / "s" / "split.json").read_text())
    kept = manifest.pop("wrench_percentiles")
    (tmp_path / "s" / "split.json").write_text(json.dumps(manifest))
    got = _train_percentiles(tmp_path / "s", TactileDataset(tmp_path / "s", "test", size=SIZE), PERCENTILES)
    for key in kept:
        assert got[key] == pytest.approx(kept[key])
