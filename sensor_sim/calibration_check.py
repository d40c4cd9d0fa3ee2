"""What a calibration may expect on presses it was not fitted on, measured on the presses it was given:
each press left out in turn, the light fitted on the others (the same contacts, blur, model, crease
penalty and sink table; the model falls back to the table and sink where the others no longer span the
field), the press rendered through that light at its fitted contact and scored against its frame.

    left = left_out_scores(background, presses, fit, mm_per_px, gel)   # one PressScore per press ([] for one)
    ratio = near_ratio(left)                                           # mean near MAE / the background's

The figure ``rig sensor calibrate`` prints as the expected error (issue 40: it printed an in-sample figure
and the bench's generic range). It is honest for this set of presses, not for any pose: a press is placed at
the contact the full fit found for it (where its own frame says it is), so a pose commanded without the
frame (the bench's frame-blind placement) scores a few points worse. numpy/cv2 only.
"""

from __future__ import annotations

import dataclasses

from sensor_sim.calibration import CalibrationResult
from sensor_sim.calibration_report import PressScore, press_scores, rendered_presses
from sensor_sim.elastomer import Elastomer
from sensor_sim.light import LightModel
from sensor_sim.light_fit import OrderChoice
from sensor_sim.press_fitter import MIN_POSITION_PRESSES, Press, PressFitter


def left_out_light(
    background, presses: list[Press], fit: CalibrationResult, mm_per_px: float, gel: Elastomer, k: int
) -> LightModel:
    """The light fitted on every press but ``presses[k]``, at the contacts, blur, model, crease penalty and
    sink table ``fit`` chose; the position terms dropped (order 0) where the others no longer pass the spread
    rule."""
    rest = [p for i, p in enumerate(presses) if i != k]
    contacts = [c for i, c in enumerate(fit.contacts) if i != k]
    fitter = PressFitter(background, rest, mm_per_px, gel, fit.light.shading)
    fitter.crease, fitter.sink_table = fit.crease, fit.sink_table
    order = fit.order
    if order.order and not (len(rest) >= MIN_POSITION_PRESSES and fitter.spread(contacts)):
        order = OrderChoice(0, 0.0, {})
    return fitter.light(contacts, fitter.sinks(contacts), fit.light.blur_mm, order)


def left_out_scores(
    background, presses: list[Press], fit: CalibrationResult, mm_per_px: float, gel: Elastomer
) -> list[PressScore]:
    """Per press, its score (``calibration_report.press_scores``) rendered through the light of the others
    at its fitted contact; [] for a single press (nothing to fit without it)."""
    if len(presses) < 2:
        return []
    scores: list[PressScore] = []
    for k, (press, contact) in enumerate(zip(presses, fit.contacts)):
        alone = dataclasses.replace(
            fit, light=left_out_light(background, presses, fit, mm_per_px, gel, k), contacts=[contact]
        )
        scores += press_scores(
            background, [press], [contact], rendered_presses(background, [press], alone, mm_per_px, gel)
        )
    return scores


def near_ratio(scores: list[PressScore]) -> float:
    """Mean near-contact MAE over the presses / the background-only frame's mean there."""
    return sum(s.mae_near for s in scores) / sum(s.background_mae_near for s in scores)
