"""Fit a sensor's optics (``LightModel``) to a no-contact frame and a few ball presses.

    result = fit_optics(background, [Press(img, ball_radius_mm=2.0), ...], mm_per_px=0.0295)
    result.light, result.contacts, result.notes

Every press is rendered the way the simulator renders any press: the ball at a pose (its
centre on the frame and its depth) through the contact solver of the simulated rig and the
renderer (``sensor_sim.press_render.PressRender``, the profile's gel), at the frames' own
resolution. The fit alternates:

1. contacts from the frame alone (``contact_find.find_contact``: the changed region, then the
   rim's circle), each depth from its contact radius through the solver (or the press's own);
2. the light for those contacts: per channel a smooth lookup table over the surface normal,
   position terms (the tables' change across the field) and sink terms (the colour change of
   pressed-in gel), linear in all of them (``light_fit``; the pixels near each contact's centre
   weigh more); the optical blur by best fit over [0, BLUR_MAX_MM] (every pixel alike); the
   tables held linear near the flat normal, the position terms and the sink table (the
   pressed-in gel's own response to a tilt) kept only when leaving a press out says they cost
   nothing / help;
3. each contact (centre, depth) refined under that light (Gauss–Newton on the rendered press,
   robust weights), then the light once more.

``result.notes`` names what a person should know: a parameter pinned at a bound of its
range, a press whose fit stopped at its depth limit. numpy/scipy/cv2 only.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from sensor_sim.contact_find import CalibrationError, Contact, find_contact
from sensor_sim.elastomer import Elastomer
from sensor_sim.light import LightModel
from sensor_sim.light_fit import OrderChoice, crease_choice
from sensor_sim.light_sink_table import sink_table_choice
from sensor_sim.press_fitter import (
    MIN_POSITION_PRESSES,
    NEAR_RADII,
    TABLE_BINS,
    Press,
    PressFitter,
    provisional_profile,
)

__all__ = [
    "MIN_POSITION_PRESSES",
    "NEAR_RADII",
    "CalibrationError",
    "CalibrationResult",
    "Contact",
    "Press",
    "find_contact",
    "fit_optics",
    "locate_press",
    "provisional_profile",
]

START_BLUR_MM = 0.1  # the first light's, which the contacts are first refined under
FINAL_ROUNDS = 1  # contacts, then light, under the chosen model


@dataclass
class CalibrationResult:
    light: LightModel
    contacts: list[Contact]
    order: OrderChoice
    notes: list[str] = field(default_factory=list)  # bounds reached, presses to look at
    seconds: float = 0.0
    crease: float = 0.0  # the tables' crease penalty the fit took (light_fit.crease_choice)
    sink_table: bool = False  # whether the light has the sink table (light_sink_table.sink_table_choice)


def _check(background: np.ndarray, presses: list[Press], mm_per_px: float) -> None:
    if background.ndim != 3 or background.shape[2] != 3:
        raise CalibrationError(f"background must be an H×W×3 colour frame, got shape {background.shape}")
    if not (math.isfinite(mm_per_px) and 0 < mm_per_px < 1):
        raise CalibrationError(f"mm_per_px must be in (0, 1) mm, got {mm_per_px}")
    if not presses:
        raise CalibrationError("no presses: at least one (three or more recommended) is needed")
    for i, p in enumerate(presses):
        name = p.name or f"press {i}"
        if p.image.shape != background.shape:
            raise CalibrationError(f"{name}: frame is {p.image.shape}, the background {background.shape}")
        if not (math.isfinite(p.ball_radius_mm) and p.ball_radius_mm > 0):
            raise CalibrationError(f"{name}: ball_radius_mm must be a finite number > 0, got {p.ball_radius_mm}")


def fit_optics(
    background: np.ndarray,
    presses: list[Press],
    mm_per_px: float,
    *,
    gel: Elastomer | None = None,
    shading: str = "multiplicative",
    refine: bool = True,
) -> CalibrationResult:
    """Fit a LightModel to ball presses over a no-contact ``background`` (BGR, H×W×3) at
    ``mm_per_px``, the presses rendered on ``gel`` (default: the simulator's 3 mm gel).
    Raises CalibrationError (one line naming the press) for unusable input."""
    t0 = time.perf_counter()
    _check(background, presses, mm_per_px)
    fitter = PressFitter(background, presses, mm_per_px, gel or Elastomer(), shading)
    contacts = [fitter.start(p) for p in presses]
    sinks = fitter.sinks(contacts)
    order0 = OrderChoice(0, 0.0, {})
    if refine:  # the contacts under a first, sharp light: a blur chosen for misplaced rims would hide them
        light = fitter.light(contacts, sinks, START_BLUR_MM, order0)
        contacts = [c if p.given else fitter.refine(light, p, c) for p, c in zip(presses, contacts)]
        sinks = fitter.sinks(contacts)
    blur = fitter.blur(contacts, sinks)
    samples = [fitter.samples(p, c, s, blur) for p, c, s in zip(presses, contacts, sinks)]
    fitter.crease = crease_choice(samples, TABLE_BINS)
    fitter.sink_table = sink_table_choice(samples, TABLE_BINS, fitter.crease)
    if fitter.spread(contacts):
        order = fitter.order(samples)
    else:
        order = order0
    light = fitter.light(contacts, sinks, blur, order)
    for _ in range(FINAL_ROUNDS if refine else 0):
        contacts = [c if p.given else fitter.refine(light, p, c) for p, c in zip(presses, contacts)]
        sinks = fitter.sinks(contacts)
        light = fitter.light(contacts, sinks, blur, order)
    seconds = time.perf_counter() - t0
    return CalibrationResult(light, contacts, order, fitter.notes, seconds, fitter.crease, fitter.sink_table)


def locate_press(
    background: np.ndarray, press: Press, mm_per_px: float, light: LightModel, *, gel: Elastomer | None = None
) -> Contact:
    """Where ``press`` is under a fitted ``light``: found from its frame, then refined by rendering
    (what a rig knows from its pose; the optics bench scores held-out presses there)."""
    _check(background, [press], mm_per_px)
    fitter = PressFitter(background, [press], mm_per_px, gel or Elastomer(), light.shading)
    start = fitter.start(press)
    return start if press.given else fitter.refine(light, press, start)
