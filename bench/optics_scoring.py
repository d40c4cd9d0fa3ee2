"""The optics bench's scoring (bench/optics_bench.py): the real frames, the two placements of a
held-out press (frame-blind and located), their scores, and the goals a row meets.

Frame-blind: the published centre and the depth at which the simulator's own contact (the same
contact solver the renders go through, a 4 mm ball) has the published touch radius, found by the
calibrator's own bisection on the solver's contact radius (sqrt(contact area / π);
``depth_for_radius``, what ``fit_optics`` starts each press from). Located: found in the press's
own frame and refined under the fitted light (``locate_press``).
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from objects.indenters import sphere
from sensor_sim.calibration import Contact, Press, locate_press, provisional_profile
from sensor_sim.elastomer import Elastomer
from sensor_sim.press_fitter import PressFitter
from sensor_sim.press_render import PressRender
from sensor_sim.registration import Registration, fit_registration

MM_PER_PX = 0.0295  # as given by the data's publisher, approximate
BALL_RADIUS_MM = 2.0  # Taxim's calibration ball (~4 mm diameter)
NEAR_RADII = 1.5  # "near": within this many published touch radii of the published centre
CENTRE_RADII = 0.4  # "centre": within this share of the placed contact's radius of its centre
RED = 2  # BGR index of the red channel
# Goals (issue 40), on the frame-blind placement: near ratio by selection, the centre ratio, the red-change spread.
NEAR_GOALS = {"spread five": 0.15, "spread triple": 0.22, "one quadrant": 0.25}
CENTRE_GOAL = 0.25
RED_STD_GOAL = 0.25  # the render's std across presses within this share of the real's


@dataclass
class Sensor:
    name: str
    background: np.ndarray
    images: list[np.ndarray]
    published: list[tuple[float, float, float]]  # centre x, y, touch radius (px)
    files: list[str]


def load(folder: Path) -> Sensor:
    background = cv2.imread(str(folder / "background.png"), cv2.IMREAD_COLOR)
    with open(folder / "presses.csv") as fh:
        rows = list(csv.DictReader(fh))
    images = [cv2.imread(str(folder / r["file"]), cv2.IMREAD_COLOR) for r in rows]
    published = [
        (float(r["touch_center_x_px"]), float(r["touch_center_y_px"]), float(r["touch_radius_px"])) for r in rows
    ]
    return Sensor(folder.name, background, images, published, [r["file"] for r in rows])


class Blind:
    """The frame-blind depths of a sensor's presses (once per press: they do not depend on the light)
    and the calibrator's spread rule, both through the calibrator's own code (``PressFitter``)."""

    def __init__(self, sensor: Sensor, gel: Elastomer):
        self.fitter = PressFitter(
            sensor.background, [Press(sensor.background, BALL_RADIUS_MM)], MM_PER_PX, gel, "multiplicative"
        )
        self.press = self.fitter.presses[0]
        self.limit_mm = self.fitter.max_depth(self.press)
        h, w = sensor.background.shape[:2]
        self.widest_px = self.radius_px(((w - 1) / 2, (h - 1) / 2), self.limit_mm)  # the solver's at the depth limit
        self.depths: dict[tuple[float, float, float], float] = {}
        self.seconds = 0.0

    def radius_px(self, centre: tuple[float, float], depth_mm: float) -> float:
        return self.fitter.contact_radius_px(self.press, Contact(centre[0], centre[1], 0.0, depth_mm))

    def depth(self, published: tuple[float, float, float]) -> float:
        """The depth (mm) at which the solver's contact at the published centre has the published radius
        (bisection: the contact radius grows with the depth; at the depth limit if it never gets there)."""
        if published not in self.depths:
            t0 = time.perf_counter()
            cx, cy, r = published
            self.depths[published] = self.fitter.depth_for_radius(self.press, Contact(cx, cy, 0.0), r)
            self.seconds += time.perf_counter() - t0
        return self.depths[published]

    def spread(self, sensor: Sensor, chosen: list[int]) -> bool:
        """The calibrator's spread rule (MIN_POSITION_PRESSES or more, centres over MIN_SPAN of the frame's
        width or height) on the published centres."""
        ok = self.fitter.spread([Contact(*sensor.published[i]) for i in chosen])
        self.fitter.notes.clear()
        return ok


@dataclass
class PressScore:
    file: str
    near: float  # MAE within NEAR_RADII published radii of the published centre
    near_bg: float  # the background-only frame's there
    whole: float
    whole_bg: float
    centre: float  # MAE within CENTRE_RADII of the located contact's radius of its centre
    centre_bg: float
    red: float  # mean red change from the background inside the published disc, the render's
    red_real: float  # the real frame's
    contact: tuple[float, float, float]  # the placed contact: centre x, y, radius (px)
    depth_mm: float


def score(sensor: Sensor, i: int, rendered: np.ndarray, contact: tuple[float, float, float], depth: float):
    """``rendered`` against press ``i``'s real frame; "centre" in the disc of ``contact`` (x, y, radius px)."""
    real = sensor.images[i].astype(np.float32)
    bg = sensor.background.astype(np.float32)
    ys, xs = np.mgrid[0 : bg.shape[0], 0 : bg.shape[1]]
    cx, cy, touch = sensor.published[i]
    dist = np.hypot(xs - cx, ys - cy)
    near, disc = dist < NEAR_RADII * touch, dist < touch
    centre = np.hypot(xs - contact[0], ys - contact[1]) < CENTRE_RADII * contact[2]
    render = rendered.astype(np.float32)
    err, base = np.abs(render - real), np.abs(bg - real)
    return PressScore(
        sensor.files[i],
        float(err[near].mean()),
        float(base[near].mean()),
        float(err.mean()),
        float(base.mean()),
        float(err[centre].mean()),
        float(base[centre].mean()),
        float((render[..., RED] - bg[..., RED])[disc].mean()),
        float((real[..., RED] - bg[..., RED])[disc].mean()),
        contact,
        depth,
    )


def score_held_out(sensor: Sensor, fit, held: list[int], gel: Elastomer, blind: Blind, placements: dict):
    """({name: blind scores} for each of ``placements`` (name → Registration of the labels), the located
    scores, the first placement's blind renders) of the held-out presses under ``fit``'s light. Every
    placement's "centre" is scored in the same disc, the located contact's (the press's own frame says
    where its contact is; it scores every placement and places only the located one)."""
    profile = provisional_profile(sensor.background, MM_PER_PX, gel, fit.light)
    press = PressRender(profile, sphere(2 * BALL_RADIUS_MM))
    blind_scores: dict[str, list[PressScore]] = {name: [] for name in placements}
    located_scores, renders = [], {}
    for i in held:
        c = locate_press(sensor.background, Press(sensor.images[i], BALL_RADIUS_MM), MM_PER_PX, fit.light, gel=gel)
        found = (c.centre_x_px, c.centre_y_px, c.radius_px)
        for k, (name, reg) in enumerate(placements.items()):
            cx, cy, touch = reg.place(*sensor.published[i])
            depth = blind.depth((cx, cy, touch))
            rendered = press.render(press.pose_of_pixel(cx, cy, -depth))
            if k == 0:
                renders[i] = rendered
            blind_scores[name].append(score(sensor, i, rendered, found, depth))
        located = press.render(press.pose_of_pixel(c.centre_x_px, c.centre_y_px, -float(c.depth_mm or 0.0)))
        located_scores.append(score(sensor, i, located, found, float(c.depth_mm or 0.0)))
    return blind_scores, located_scores, renders


def registration_of(sensor: Sensor, fit, chosen: list[int], blind: Blind) -> Registration:
    """The calibration presses' labels against where the calibration found them (``fit.contacts``); labels
    wider than the solver's widest contact for the ball left out of the radius ratio; the centre offset
    only from presses that pass the calibrator's spread rule (on the published centres)."""
    return fit_registration(
        [sensor.published[i] for i in chosen],
        [(c.centre_x_px, c.centre_y_px, c.radius_px) for c in fit.contacts],
        [sensor.files[i] for i in chosen],
        reach_px=blind.widest_px,
        spread=blind.spread(sensor, chosen),
    )


@dataclass
class Summary:
    near: float  # mean near MAE over the held-out presses / the background's mean
    worst: PressScore
    below: int  # presses whose whole-frame MAE is below the background's
    n: int
    centre: float  # mean centre MAE / the background's mean in the same discs
    red_std: float  # std across presses of the render's red change
    red_std_real: float
    red_corr: float  # nan under three presses
    depth_mm: float  # mean placement depth

    @property
    def red_ratio(self) -> float:
        return self.red_std / self.red_std_real if self.n >= 2 and self.red_std_real > 0 else math.nan

    def cells(self) -> list[str]:
        red = f"{self.red_std:.2f} / {self.red_std_real:.2f} ({self.red_ratio:.2f})" if self.n >= 2 else "n/a (1)"
        corr = f"{self.red_corr:+.2f}" if math.isfinite(self.red_corr) else "–"
        return [
            f"{self.near:.0%}",
            f"{self.worst.file.removesuffix('.png')} {self.worst.near / self.worst.near_bg:.0%}",
            f"{self.below} of {self.n}",
            f"{self.centre:.0%}",
            red,
            corr,
        ]


def summarise(scores: list[PressScore]) -> Summary:
    red = np.array([s.red for s in scores])
    real = np.array([s.red_real for s in scores])
    corr = float(np.corrcoef(red, real)[0, 1]) if len(scores) >= 3 else math.nan
    return Summary(
        float(np.mean([s.near for s in scores]) / np.mean([s.near_bg for s in scores])),
        max(scores, key=lambda s: s.near / s.near_bg),
        sum(s.whole < s.whole_bg for s in scores),
        len(scores),
        float(np.mean([s.centre for s in scores]) / np.mean([s.centre_bg for s in scores])),
        float(red.std()),
        float(real.std()),
        corr,
        float(np.mean([s.depth_mm for s in scores])),
    )


def near_goal(sensor: str, selection: str, k: int) -> str:
    """Which near goal a row answers: the Mini's presses all lie near the frame's centre (none of its
    selections is spread over the field), so its rows answer the one-quadrant goal."""
    if sensor == "gelsight_mini" or selection.startswith("one quadrant"):
        return "one quadrant"
    return "spread five" if k == 5 else "spread triple"


def goals(s: Summary, goal: str) -> tuple[dict[str, bool | None], str]:
    """Each goal met (True), missed (False) or not measurable (None); and the cell text."""
    met: dict[str, bool | None] = {
        f"near ≤ {NEAR_GOALS[goal]:.0%}": s.near <= NEAR_GOALS[goal],
        f"centre ≤ {CENTRE_GOAL:.0%}": s.centre <= CENTRE_GOAL,
        "whole": s.below == s.n,
        "red std": abs(s.red_ratio - 1) <= RED_STD_GOAL if math.isfinite(s.red_ratio) else None,
    }
    mark = {True: "✓", False: "✗", None: "n/a"}
    return met, ", ".join(f"{name} {mark[v]}" for name, v in met.items())
