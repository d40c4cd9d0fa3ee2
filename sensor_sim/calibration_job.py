"""``rig sensor calibrate``'s work from its parsed options: fit the optics to the presses, score them in
sample and left out, measure the noise, write the profile (read back as every command reads it) and the
contact sheet; the command prints what ``Calibrated`` holds.

    done = calibrate(background, presses, mm_per_px, gel, out=Path("sensor.toml"), sheet=..., name="mine",
                     source="rig sensor calibrate: presses/")

Raises CalibrationError, ProfileError, PhysicsInputError, ValueError or OSError, one line each; nothing is
written before the fit and its scores are done, and the profile is checked by reading it back.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sensor_sim.calibration import CalibrationResult, Press, fit_optics
from sensor_sim.calibration_check import left_out_scores, near_ratio
from sensor_sim.calibration_report import (
    Coverage,
    PressScore,
    contact_sheet,
    estimate_noise,
    field_coverage,
    press_scores,
    profile_from_fit,
    rendered_presses,
)
from sensor_sim.elastomer import Elastomer
from sensor_sim.noise import SensorNoise
from sensor_sim.profile import SensorProfile

MODEL_WORDS = (
    "table and sink",
    "table, sink and their change across the field",
    "table, sink and their change across the field, the sink's quadratic in depth and position",
)


@dataclass
class Calibrated:
    fit: CalibrationResult
    scores: list[PressScore]  # in sample: each press rendered through the light fitted on all of them
    left_out: list[PressScore]  # each press rendered through the light of the others ([] for one press)
    noise: SensorNoise
    profile: SensorProfile
    written: Path  # the profile TOML (its background PNG beside it)
    sheet: Path
    coverage: Coverage

    @property
    def model_words(self) -> str:
        """The light model the fit chose, in words."""
        return MODEL_WORDS[self.fit.order.order]

    @property
    def expected(self) -> float | None:
        """Near-contact error of a press not fitted / the background's (left out in turn); None for one press."""
        return near_ratio(self.left_out) if self.left_out else None

    @property
    def worst_left_out(self) -> PressScore | None:
        return max(self.left_out, key=lambda s: s.mae_near / s.background_mae_near) if self.left_out else None

    @property
    def no_better(self) -> list[str]:
        """Presses the render fits no better than the background near the contact."""
        return [s.name for s in self.scores if s.mae_near >= s.background_mae_near]


def calibrate(
    background: np.ndarray,
    presses: list[Press],
    mm_per_px: float,
    gel: Elastomer,
    *,
    out: Path,
    sheet: Path,
    name: str,
    source: str,
    noise_std: float | None = None,
    frame_px: int | None = None,
    field_mm: tuple[float, float] | None = None,
) -> Calibrated:
    """Fit, score, write ``out`` (and its background PNG) and the contact ``sheet``; see the module docstring."""
    import cv2

    from sensor_sim.profile import load_profile
    from sensor_sim.profile_save import save_profile

    fit = fit_optics(background, presses, mm_per_px, gel=gel)
    renders = rendered_presses(background, presses, fit, mm_per_px, gel)
    scores = press_scores(background, presses, fit.contacts, renders)
    left_out = left_out_scores(background, presses, fit, mm_per_px, gel)
    noise = (
        SensorNoise((noise_std,) * 3) if noise_std is not None else estimate_noise(background, presses, fit.contacts)
    )
    profile = profile_from_fit(
        background,
        fit,
        mm_per_px,
        name=name,
        source=source.replace('"', "'"),
        noise=noise,
        gel=gel,
        frame_width_px=frame_px,
        field_mm=field_mm,
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    written = save_profile(profile, out)
    load_profile(written)  # what was written is what every command will read
    if not cv2.imwrite(str(sheet), contact_sheet(presses, fit.contacts, renders, scores)):
        raise OSError(f"--sheet {sheet}: cannot write the image")
    coverage = field_coverage(fit.contacts, background.shape)
    return Calibrated(fit, scores, left_out, noise, profile, written, sheet, coverage)
