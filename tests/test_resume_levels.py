"""Resume from a clean press (issue 36; acquisition/resume_plan.py): a run interrupted in a press, a
shear or a twist is resumed from the start of the level it broke, pressed again from the gel's surface,
and ends complete, valid and inside its force limits, with the frames it took again marked and the
ones they replace kept apart in superseded/."""

from __future__ import annotations

import re

import h5py
import numpy as np
import pytest
from test_acquisition import ctrl_c, interrupt_at, run

from acquisition import schema as S
from dataset.runs import validate
from protocols.plan import Plan
from protocols.spec import load_protocol


def fast(name: str, folder) -> object:
    """The library protocol at 100x its speeds (inside the simulated rig's envelope), captured at 2 Hz."""
    text = load_protocol(name).text
    text = re.sub(r"(?m)^speed_mm_s = [0-9.]+", "speed_mm_s = 1.0", text)
    text = re.sub(r"(?m)^twist_speed_deg_s = [0-9.]+", "twist_speed_deg_s = 5.0", text)
    text = re.sub(r"(?m)^rate_hz = [0-9.]+", "rate_hz = 2.0", text)
    path = folder / f"{name}.toml"
    path.write_text(text)
    return load_protocol(path)


def phase_at(plan: Plan, k: int) -> tuple[str, int]:
    step, _ = plan.locate(plan.capture_time(k))
    return step.phase, step.level


def level_start(plan: Plan, level: int) -> int:
    """The first capture index of ``level``."""
    return next(k for k in range(plan.frame_count) if phase_at(plan, k)[1] == level)


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize(
    "name, stops",
    [
        ("circle8mm", [(37, "shear", 2), (66, "press", 3), (94, "twist", 3)]),
        ("woven", [(62, "twist", 2)]),
    ],
)
@pytest.mark.realtime  # signals at chosen moments of real time
def test_an_interrupted_level_is_pressed_again_from_its_start(name, stops, tmp_path):
    protocol = fast(name, tmp_path)
    plan = Plan.of(protocol)
    out = tmp_path / "run.h5"
    resume = False
    expected_retakes = []  # (retake number, first k, frames superseded)
    for number, (frames, phase, level) in enumerate(stops, start=1):
        assert phase_at(plan, frames - 1) == (phase, level), phase_at(plan, frames - 1)  # interrupted there
        result, _ = run(protocol, out, resume=resume, progress=interrupt_at(frames, ctrl_c))
        assert result.status == "interrupted" and result.frames == frames, result.reason
        first = level_start(plan, level)
        expected_retakes.append((number, first, frames - first))
        resume = True
    result, _ = run(protocol, out, resume=True)
    assert result.status == "complete", result.reason  # never "aborted" because of how it resumed
    assert validate(out) == []
    with h5py.File(out, "r") as f:
        np.testing.assert_array_equal(f[S.CAPTURE_INDEX][()], np.arange(plan.frame_count))
        retake = f[S.RETAKE][()]
        peak = np.abs(f[S.WRENCH][()][:, :3]).max(axis=0)
        forces = re.search(r"max_force_N = \[([^\]]*)\]", f.attrs[S.ATTR_RIG_CONFIG]).group(1)
        limits = np.array([float(v) for v in forces.split(",")])  # the limits the run ran under
        superseded = f[S.SUPERSEDED]
        assert sorted(superseded) == [f"retake-{n}" for n, _, _ in expected_retakes]
        for number, first, count in expected_retakes:
            g = superseded[f"retake-{number}"]
            assert g.attrs["first_capture_index"] == first and g.attrs["frames"] == count == g[S.FRAMES].shape[0]
            assert "pressed level" in g.attrs["why"] and "the run stopped (Ctrl-C" in g.attrs["why"]
            # the frames that replace them say so; a later retake of the same captures wins
            later = [n for n, lo, c in expected_retakes if n > number and lo <= first < lo + c]
            if not later:
                assert (retake[first : first + count] == number).all(), retake[first : first + count]
    assert (peak < limits).all(), f"peak {peak} N against limits {limits} N"
    marked = int((retake > 0).sum())
    assert marked == len({k for _, lo, c in expected_retakes for k in range(lo, lo + c)})
