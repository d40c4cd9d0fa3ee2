"""Comparisons that survive a second seed (issue 27): candidates, bootstrap intervals, seed spreads,
the comparison's report with its baselines and verdict; the physics render at the depth Fz implies."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from model.compare.compare import Candidate, Result, summary
from model.compare.compare_report import verdict, write_compare_report
from model.denoiser.config import ModelConfig
from model.evaluation.intervals import bootstrap_interval, differs, seed_spread


def test_a_candidate_is_a_conditioning_then_model_fields():
    c = Candidate.parse("physics,physics_depth=force,target=physics_residual")
    cfg = c.config(ModelConfig())
    assert (cfg.conditioning, cfg.physics_depth, cfg.target) == ("physics", "force", "physics_residual")
    assert cfg.force_depth and c.folder == "physics_physics_depth_force_target_physics_residual"
    assert Candidate.parse("plane+embedding").folder == "plane-embedding"
    with pytest.raises(ValueError, match="expected a conditioning first"):
        Candidate.parse("physics_depth=force")
    with pytest.raises(ValueError, match="'colour=red' is not key=value of a model field"):
        Candidate.parse("physics,colour=red")
    with pytest.raises(ValueError, match="physics_depth force .* needs physics conditioning"):
        Candidate.parse("plane,physics_depth=force").config(ModelConfig())


def test_bootstrap_interval_is_fixed_and_holds_the_mean():
    rng = np.random.default_rng(0)
    v = rng.normal(10, 2, 40)
    low, high = bootstrap_interval(v)
    assert low < v.mean() < high and (low, high) == bootstrap_interval(v)
    assert high - low == pytest.approx(2 * 1.96 * 2 / math.sqrt(40), rel=0.35)
    assert all(math.isnan(x) for x in bootstrap_interval([3.0]))


def test_a_difference_counts_only_beyond_the_seed_spread():
    a, b = seed_spread([4.17, 4.32, 4.20]), seed_spread([4.25, 5.07, 4.6])
    assert not differs(a, b)  # issue 27's physics vs plane: the order flips with the seed
    assert differs(seed_spread([4.1, 4.2, 4.3]), seed_spread([8.0, 8.5, 9.1]))
    assert not differs(seed_spread([4.1]), seed_spread([9.0]))  # one seed: no spread, no verdict
    assert seed_spread([1.0, 3.0]).text() == "2.00 ± 1.41"


def _part(mse: float, k: float, tmp: str) -> dict:
    row = {"setting": "ddim, 10 steps", "mse": mse, "mae": 2.0, "ssim": 0.9, "psnr": 30.0, "images": 5}
    base = {
        "setting": "background (the run's no-contact frame)",
        "mse": 49.2,
        "mae": 3.6,
        "ssim": 0.84,
        "psnr": 31.3,
        "ci": {"mse": [40.1, 59.4]},
    }
    return {
        "model": [row],
        "baselines": [base],
        "physics_render": {
            "setting": "physics render",
            "mse": 12.2,
            "mae": 2.4,
            "ssim": 0.97,
            "psnr": 37.7,
            "ci": {"mse": [7.7, 17.6]},
        },
        "force_sweep": [{"component": "Fz", "area_exponent": k, "monotonic": True}],
        "real_frames_exponent": {
            "k": 0.4,
            "low": 0.2,
            "high": 0.6,
            "frames": 24,
            "fz_low": 1.18,
            "fz_high": 1.78,
            "source": f"24 real frames of {tmp}/x/run.h5",
        },
    }


def test_the_comparison_report_has_spreads_baselines_a_verdict_and_no_paths(tmp_path):
    results = [Result("plane", s, "", {"test": _part(m, 0.05, str(tmp_path))}) for s, m in enumerate((9.0, 9.5, 8.8))]
    results += [
        Result("physics,physics_depth=force", s, "", {"test": _part(m, 0.4, str(tmp_path))})
        for s, m in enumerate((4.1, 4.3, 4.0))
    ]
    results += [Result("physics", s, "", {"test": _part(m, 0.1, str(tmp_path))}) for s, m in enumerate((4.2, 4.6, 3.9))]
    s = summary(results)
    entry = s["test"]["candidates"]["physics,physics_depth=force"]
    assert entry["mse"]["n"] == 3 and entry["mse"]["mean"] == pytest.approx(4.1333, abs=1e-3)
    assert entry["k"]["mean"] == pytest.approx(0.4) and entry["monotonic"] == [1, 1, 1]
    line = verdict(s["test"]["candidates"])
    assert line.startswith("**Verdict**: `physics,physics_depth=force` has the lowest mean MSE (4.13)")
    assert "ahead of `plane` (9.10) beyond the seed spread" in line and "not settled against `physics`" in line
    path = write_compare_report(s, tmp_path / "cmp", title="t", context={"split": "split"})
    text = path.read_text()
    assert "| baseline: background (the run's no-contact frame) | — | 49.20 (40.10–59.40) |" in text
    assert "| baseline: physics render |" in text
    assert "| `plane` (ddim, 10 steps) | 0, 1, 2 | 9.10 ± 0.36 [8.80, 9.50] |" in text
    assert "k = +0.40 [+0.20, +0.60]" in text
    assert str(tmp_path) not in text and str(tmp_path) not in (tmp_path / "cmp" / "compare.json").read_text()
    assert json.loads((tmp_path / "cmp" / "compare.json").read_text())["test"]["frames"] == 5


def test_compare_refuses_a_bad_candidate_in_one_line(tmp_path):
    from typer.testing import CliRunner

    from cli.main import app

    r = CliRunner().invoke(
        app, ["model", "compare", "--data", str(tmp_path), "--out", str(tmp_path / "o"), "--candidate", "physics,x=1"]
    )
    assert r.exit_code == 1 and "Traceback" not in r.output
    assert "'x=1' is not key=value of a model field" in r.output and len(r.output.strip().splitlines()) == 1


class _Renderer:
    """A stand-in for ObjectRender: depth = Fz / 2 mm, up to 3 mm (gel 2 mm × 1.5)."""

    class contact:  # noqa: N801 (the attribute path force_pose reads)
        class solver:
            class gel:
                thickness_mm = 2.0

    def pose_at_force(self, x, y, theta, fz):
        if fz / 2 > 3.0:
            raise ValueError(f"Fz {fz} N is beyond what the gel gives")
        return np.array([x, y, -fz / 2, theta])


def test_the_force_decides_the_depth_of_the_physics_render():
    from model.conditioning.force_render import force_pose

    at, note = force_pose(_Renderer(), (1.0, 2.0, -0.1, 5.0), 2.0)
    assert at.tolist() == [1.0, 2.0, -1.0, 5.0] and note == ""  # the pose's z is not used
    at, note = force_pose(_Renderer(), (1.0, 2.0, -0.1, 5.0), 10.0)
    assert at[2] == -3.0 and "beyond" in note and "rendered at 3 mm" in note  # past the gel: its deepest
    at, note = force_pose(_Renderer(), (0.0, 0.0, -0.5, 0.0), 0.0)
    assert at[2] == 0.0 and note.startswith("no load")


def test_the_comparison_holds_settings_to_the_same_exponent_as_each_runs_report():
    from model.compare.compare_report import force_verdict

    entry = {
        "real_exponent_at_poses": 0.51,  # real frames at the sweep's poses at several forces
        "real_frames_exponent": {"k": 0.62, "low": 0.56, "high": 0.68},
        "render_exponent": 0.66,
        "candidates": {"plane": {"k": {"mean": 0.48, "std": 0.01, "low": 0.47, "high": 0.49, "n": 3}}},
    }
    line = force_verdict(entry)
    assert (
        "held to the reference exponent +0.51" in line
        and "the real frames at the sweep's poses" in line
        and "(within)" in line
    )
    entry["real_exponent_at_poses"] = None  # none at the poses: the frames across poses (interval above zero)
    assert "held to the reference exponent +0.62" in force_verdict(entry)
    # a summary made now carries the one reference each run's report names, and is held to that
    entry["reference_exponent"], entry["reference_source"] = 0.71, "the physics render at the sweep's 8 pose(s)"
    line = force_verdict(entry)
    assert "held to the reference exponent +0.71" in line and "8 pose(s)" in line and "(outside)" in line


def test_compare_steps_makes_each_step_count_a_setting_of_its_own(monkeypatch, tmp_path):
    """`compare --steps 400,1200` (issue 37): each candidate at each step count, named and foldered apart,
    each trained for its own steps."""
    import typer

    import model.training.build
    from cli.compare_cmd import _step_counts
    from model.compare.compare import train_one

    assert _step_counts("400,1200") == [400, 1200] and _step_counts(None) == []
    for bad in ("400,x", "0", "400,400", ""):
        with pytest.raises(typer.BadParameter, match="--steps"):
            _step_counts(bad)
    text = "physics,target=physics_residual,residual_gain=8"
    short, long = (Candidate.parse(text).with_steps(n) for n in (400, 1200))
    assert long.name == f"{text} @ 1200 steps" and short.folder != long.folder
    seen = []

    class Trainer:
        def train(self):
            pass

        def save(self):
            pass

    def fake_build(cfg, train_cfg, *args, **kwargs):
        seen.append((cfg.residual_gain, train_cfg.steps, train_cfg.checkpoint_every))
        return Trainer()

    monkeypatch.setattr(model.training.build, "build", fake_build)
    for cand in (short, long):
        train_one(cand, 0, ModelConfig(), {"steps": 400, "batch_size": 2}, tmp_path, tmp_path / cand.folder)
    assert seen == [(8.0, 400, 400), (8.0, 1200, 1200)]
