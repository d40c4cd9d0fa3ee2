"""Where a press's labels put its contact against where its frame shows it, learnt from the calibration
presses and applied to presses placed without their frames.

    reg = fit_registration(labels, located)       # labels: (centre x, centre y, radius) px per press
    x, y, r = reg.place(*label)                   # a new press's labels, corrected

A dataset's published centres and radii, or a rig's commanded poses, are not where the gel shows the
contact: the original GelSight's contacts sit +2.4, +1.5 px (x, y) from their published centres on
average, and the GelSight Mini's published radii are about twice the contact the solver makes at the
press's refined depth (docs/benchmarks.md). A calibration finds each of its presses in its frame, so
it knows both for those presses; the registration is their median difference (centre, px) and median
ratio (radius): robust to one mislabelled press of four. Each of the two is taken only where leaving
presses out says it predicts the press left out better than the labels as given, from three presses
or more (leaving one out of two checks one press against one): the original GelSight's published
radii are right on average, and a ratio of 0.95 from three presses two of which the 4 mm ball cannot
fill placed its other presses 0.3 mm too shallow. The centre offset is taken only from presses that pass
the calibrator's spread rule (three or more spanning 40 % of the frame's width or of its height, as for
the light's position terms; the GelSight Mini's, all near the centre, do not): the labels' offset
changes across the field (the original GelSight's bottom-left presses +3.1, −2.4 px; +2.4, +1.5 px
over the field), and one quadrant's offset moved the other quadrants' presses away from their
contacts. The radius ratio is a labelling convention, the same everywhere. Nothing here reads a
frame. numpy only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

# A label radius more than this factor from the contact the frame shows is not a label of that press.
RADIUS_SCALE_RANGE = (0.25, 4.0)
MIN_PRESSES = 3  # a correction is checked by leaving each press out of at least two others


class RegistrationError(ValueError):
    """Labels that cannot be registered: one line naming the press and the value."""


@dataclass(frozen=True)
class Registration:
    """Add (dx_px, dy_px) to a labelled centre and multiply a labelled radius by radius_scale."""

    dx_px: float = 0.0
    dy_px: float = 0.0
    radius_scale: float = 1.0
    presses: int = 0  # how many presses it was learnt from (0: the identity)
    radius_presses: int = 0  # how many of them the radius ratio was learnt from (those within reach)
    centre_taken: bool = False  # whether the presses were spread and leaving presses out kept the offset
    radius_taken: bool = False  # whether leaving presses out kept the radius ratio (else 1)

    def place(self, x_px: float, y_px: float, radius_px: float) -> tuple[float, float, float]:
        return x_px + self.dx_px, y_px + self.dy_px, radius_px * self.radius_scale

    def describe(self) -> str:
        if not (self.centre_taken or self.radius_taken):
            checked = f" (leaving presses out of {self.presses}: no gain)" if self.presses else ""
            return "labels taken as given" + checked
        centre = f"centre {self.dx_px:+.1f}, {self.dy_px:+.1f} px" if self.centre_taken else "centre as labelled"
        radius = "radius as labelled"
        if self.radius_taken:
            of = f" (of {self.radius_presses} within reach)" if self.radius_presses != self.presses else ""
            radius = f"radius ×{self.radius_scale:.2f}{of}"
        return f"labels registered on {self.presses} presses: {centre}, {radius}"


def _triple(what: str, values: Sequence[float]) -> tuple[float, float, float]:
    if len(values) != 3:
        raise RegistrationError(f"{what}: expected (centre x, centre y, radius) px, got {len(values)} values")
    try:
        x, y, r = (float(v) for v in values)
    except (TypeError, ValueError):
        raise RegistrationError(f"{what}: expected numbers (centre x, centre y, radius) px, got {values!r}") from None
    if not all(math.isfinite(v) for v in (x, y, r)) or r <= 0:
        raise RegistrationError(f"{what}: expected finite centre and a radius > 0 px, got ({x}, {y}, {r})")
    return x, y, r


def fit_registration(
    labels: Sequence[Sequence[float]],
    located: Sequence[Sequence[float]],
    names: Sequence[str] | None = None,
    reach_px: float | None = None,
    spread: bool = True,
) -> Registration:
    """The median centre offset and radius ratio of ``located`` against ``labels`` (both (x, y, radius)
    px per press, in the same order), each where ``_left_out_gain`` says so. ``reach_px``: the widest
    contact the solver makes for the ball (its radius at the depth limit); a press labelled wider says
    nothing of the ratio (its located contact cannot be wider: the original GelSight's press_38 and
    press_44) and is left out of it. ``spread``: whether the presses span the field (else no centre
    offset). No presses: the identity. Raises RegistrationError for a
    non-finite value, a radius ≤ 0, unequal lengths, a reach that is not a finite number > 0, or a press
    within reach whose ratio is outside RADIUS_SCALE_RANGE."""
    if len(labels) != len(located):
        raise RegistrationError(f"{len(labels)} labelled presses but {len(located)} located")
    names = list(names) if names is not None else [f"press {i}" for i in range(len(labels))]
    if len(names) != len(labels):
        raise RegistrationError(f"{len(labels)} labelled presses but {len(names)} names")
    if reach_px is not None and not (math.isfinite(reach_px) and reach_px > 0):
        raise RegistrationError(f"reach_px: expected a finite number > 0 px, got {reach_px}")
    if len(labels) == 0:
        return Registration()
    lab = np.array([_triple(f"{n}: label", v) for n, v in zip(names, labels)])
    loc = np.array([_triple(f"{n}: located contact", v) for n, v in zip(names, located)])
    ratio = loc[:, 2] / lab[:, 2]
    within = np.ones(len(lab), bool) if reach_px is None else lab[:, 2] <= reach_px
    lo, hi = RADIUS_SCALE_RANGE
    for n, q, ok in zip(names, ratio, within):
        if ok and not lo <= q <= hi:
            raise RegistrationError(
                f"{n}: located contact radius is ×{q:.2f} the labelled one, expected ×{lo:g} to ×{hi:g}"
            )
    offset = loc[:, :2] - lab[:, :2]
    log_ratio = np.log(ratio[within])[:, None]
    centre_taken, radius_taken = spread and _left_out_gain(offset), _left_out_gain(log_ratio)
    dx, dy = np.median(offset, axis=0) if centre_taken else (0.0, 0.0)
    scale = float(np.exp(np.median(log_ratio))) if radius_taken else 1.0  # the median the check used
    count = int(within.sum())
    return Registration(float(dx), float(dy), scale, len(labels), count, centre_taken, radius_taken)


def _left_out_gain(errors: np.ndarray) -> bool:
    """Whether each press's label error (rows: px offsets or log radius ratios) is predicted better by
    the median of the other presses' than by none: the mean distance left over, against the labels'
    own. Fewer than MIN_PRESSES: False."""
    n = len(errors)
    if n < MIN_PRESSES:
        return False
    left = [np.linalg.norm(errors[i] - np.median(np.delete(errors, i, axis=0), axis=0)) for i in range(n)]
    return float(np.mean(left)) < float(np.mean(np.linalg.norm(errors, axis=1)))
