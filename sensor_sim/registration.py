"""Where a press's labels put its contact against where its frame shows it, learnt from the calibration
presses and applied to presses placed without their frames.

    reg = fit_registration(labels, located)       # labels: (centre x, centre y, radius) px per press
    x, y, r = reg.place(*label)                   # a new press's labels, corrected

A dataset's published centres and radii, or a rig's commanded poses, are not where the gel shows the
contact: the original GelSight's published centres sit +2.7 px in x from the visible contacts on
average, and the GelSight Mini's published radii are about twice the contact the solver makes at the
press's refined depth (docs/benchmarks.md). A calibration finds each of its presses in its frame, so
it knows both for those presses; the registration is their median difference (centre, px) and median
ratio (radius): robust to one mislabelled press of four. Each of the two is taken only where leaving
presses out says it predicts the press left out better than the labels as given (two presses or more):
the original GelSight's published radii are right on average, and a ratio of 0.95 from three presses
two of which the 4 mm ball cannot fill placed its other presses 0.3 mm too shallow. Nothing here reads
a frame. numpy only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

# A label radius more than this factor from the contact the frame shows is not a label of that press.
RADIUS_SCALE_RANGE = (0.25, 4.0)


class RegistrationError(ValueError):
    """Labels that cannot be registered: one line naming the press and the value."""


@dataclass(frozen=True)
class Registration:
    """Add (dx_px, dy_px) to a labelled centre and multiply a labelled radius by radius_scale."""

    dx_px: float = 0.0
    dy_px: float = 0.0
    radius_scale: float = 1.0
    presses: int = 0  # how many presses it was learnt from (0: the identity)
    centre_taken: bool = False  # whether leaving presses out kept the centre offset (else 0, 0)
    radius_taken: bool = False  # whether leaving presses out kept the radius ratio (else 1)

    def place(self, x_px: float, y_px: float, radius_px: float) -> tuple[float, float, float]:
        return x_px + self.dx_px, y_px + self.dy_px, radius_px * self.radius_scale

    def describe(self) -> str:
        if not (self.centre_taken or self.radius_taken):
            checked = f" (leaving presses out of {self.presses}: no gain)" if self.presses else ""
            return "labels taken as given" + checked
        centre = f"centre {self.dx_px:+.1f}, {self.dy_px:+.1f} px" if self.centre_taken else "centre as labelled"
        radius = f"radius ×{self.radius_scale:.2f}" if self.radius_taken else "radius as labelled"
        return f"labels registered on {self.presses} presses: {centre}, {radius}"


def _triple(what: str, values: Sequence[float]) -> tuple[float, float, float]:
    if len(values) != 3:
        raise RegistrationError(f"{what}: expected (centre x, centre y, radius) px, got {len(values)} values")
    x, y, r = (float(v) for v in values)
    if not all(math.isfinite(v) for v in (x, y, r)) or r <= 0:
        raise RegistrationError(f"{what}: expected finite centre and a radius > 0 px, got ({x}, {y}, {r})")
    return x, y, r


def fit_registration(
    labels: Sequence[Sequence[float]],
    located: Sequence[Sequence[float]],
    names: Sequence[str] | None = None,
    reach_px: float | None = None,
) -> Registration:
    """The median centre offset and radius ratio of ``located`` against ``labels`` (both (x, y, radius)
    px per press, in the same order), each where ``_left_out_gain`` says so. ``reach_px``: the widest
    contact the solver makes for the ball (its radius at the depth limit); a press labelled wider says
    nothing of the ratio (its located contact cannot be wider: the original GelSight's press_38 and
    press_44) and is left out of it. No presses: the identity. Raises RegistrationError for a
    non-finite value, a radius ≤ 0, unequal lengths or a ratio outside RADIUS_SCALE_RANGE."""
    if len(labels) != len(located):
        raise RegistrationError(f"{len(labels)} labelled presses but {len(located)} located")
    if not labels:
        return Registration()
    names = list(names) if names is not None else [f"press {i}" for i in range(len(labels))]
    lab = np.array([_triple(f"{n}: label", v) for n, v in zip(names, labels)])
    loc = np.array([_triple(f"{n}: located contact", v) for n, v in zip(names, located)])
    ratio = loc[:, 2] / lab[:, 2]
    lo, hi = RADIUS_SCALE_RANGE
    for n, q in zip(names, ratio):
        if not lo <= q <= hi:
            raise RegistrationError(
                f"{n}: located contact radius is ×{q:.2f} the labelled one, expected ×{lo:g} to ×{hi:g}"
            )
    offset = loc[:, :2] - lab[:, :2]
    within = np.ones(len(lab), bool) if reach_px is None else lab[:, 2] <= reach_px
    log_ratio = np.log(ratio[within])[:, None]
    centre_taken, radius_taken = _left_out_gain(offset), _left_out_gain(log_ratio)
    dx, dy = np.median(offset, axis=0) if centre_taken else (0.0, 0.0)
    scale = float(np.median(ratio[within])) if radius_taken else 1.0
    return Registration(float(dx), float(dy), scale, len(labels), centre_taken, radius_taken)


def _left_out_gain(errors: np.ndarray) -> bool:
    """Whether each press's label error (rows: px offsets or log radius ratios) is predicted better by
    the median of the other presses' than by none: the mean distance left over, against the labels'
    own. One press: no one to leave out, False."""
    n = len(errors)
    if n < 2:
        return False
    left = [np.linalg.norm(errors[i] - np.median(np.delete(errors, i, axis=0), axis=0)) for i in range(n)]
    return float(np.mean(left)) < float(np.mean(np.linalg.norm(errors, axis=1)))
