"""The calibration's steps on one set of presses, each a method of ``PressFitter``: a press's contact from
its frame (``start``), its depth from its contact radius through the solver (``depth_for_radius``), the
light for given contacts (``light``), the optical blur (``blur``), the spread rule and the position terms'
order (``spread``, ``order``), and a contact refined under a light by rendering (``refine``).

    fitter = PressFitter(background, presses, mm_per_px, gel, shading)
    contacts = [fitter.start(p) for p in presses]
    light = fitter.light(contacts, fitter.sinks(contacts), blur_mm, order)

``calibration.fit_optics`` runs them in order; ``calibration_check`` (a press left out) and the optics
bench (frame-blind depths, the spread rule) call them on their own. numpy/scipy/cv2 only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from objects.indenters import sphere
from objects.pose import Pose
from sensor_sim.contact_find import Contact, find_contact
from sensor_sim.elastomer import Elastomer
from sensor_sim.light import LightModel
from sensor_sim.light_fit import (
    POSITION_RIDGES,
    OrderChoice,
    PressSamples,
    choose_order,
    fit_light_terms,
    held_out_mae,
)
from sensor_sim.light_sink_table import fit_alternating
from sensor_sim.light_tables import normal_lookup
from sensor_sim.noise import SensorNoise

TABLE_BINS = 21  # normal grid: 0.1 steps in nx, ny
FIT_RADII = 3.0  # pixels within this many contact radii of a press enter the fit
NEAR_RADII = 1.5  # "near the contact": where the blur is chosen (and renders are scored)
CENTRE_RADII = 0.4  # "the contact's centre" (issue 40's measure): where the sink table is judged
SAMPLE_STEP = 2  # every second pixel (rows and columns) enters the fit
# A fitted pixel d contact radii from the centre weighs max(d, CENTRE_WEIGHT_RADII) ** -CENTRE_WEIGHT_POWER
# (mean 1 per press), so the few pixels of near-vertical normals at the centre are not outvoted by the wide
# ring of gel outside the contact (issue 40: the centre's point). Power 1 (every ring alike) is truer at the
# centre still but costs the GelSight Mini's shallow presses 3-4 points near the contact.
CENTRE_WEIGHT_RADII, CENTRE_WEIGHT_POWER = 0.15, 0.5
BLUR_MAX_MM = 0.5  # the optical blur's range is [0, BLUR_MAX_MM]
MIN_POSITION_PRESSES, MIN_SPAN = 3, 0.4  # presses needed, and the share of the field they span, for position terms
MIN_CHOICE_PRESSES = 4  # fewer: too few to judge the position terms by leaving a press out (two left)
BLUR_STEPS = 6  # golden-section steps on the blur (to ~0.01 mm over the whole range)
REFINE_ITERATIONS = 8
DEPTH_STEP_MM = 0.01  # finite differences of the refinement
CENTRE_STEP_PX = 0.5


@dataclass(frozen=True)
class Press:
    """One real press: a frame (BGR, the background's size) of a ball of known radius.

    ``centre_px`` (x, y) and ``radius_px`` override the contact found automatically (then used
    as given); ``depth_mm`` (from the stage's z) is the starting depth instead of the one the
    contact radius gives.
    """

    image: np.ndarray
    ball_radius_mm: float
    centre_px: tuple[float, float] | None = None
    radius_px: float | None = None
    depth_mm: float | None = None
    name: str = ""

    @property
    def given(self) -> bool:
        return bool(self.centre_px and self.radius_px)


def provisional_profile(background: np.ndarray, mm_per_px: float, gel: Elastomer, light: LightModel):
    """A profile of the frames as they are (their size and scale, the given gel) with ``light``:
    what the calibration renders presses through."""
    from sensor_sim.profile import SensorProfile

    h, w = background.shape[:2]
    return SensorProfile(
        name="calibrating",
        source="",
        width_px=w,
        height_px=h,
        mm_per_px=mm_per_px,
        gel_thickness_mm=gel.thickness_mm,
        gel_E_MPa=gel.E_MPa,
        noise=SensorNoise((0.0, 0.0, 0.0)),
        light=light,
        background=background,
        format=light.profile_format,  # 4: the quadratic sink field; 5: the sink table
    )


class PressFitter:
    """The state of one calibration: the frames, a renderer per ball size, the contacts."""

    def __init__(self, background: np.ndarray, presses: list[Press], mm_per_px: float, gel: Elastomer, shading: str):
        from sensor_sim.press_render import PressRender

        self.background = background
        self.bg = background.astype(np.float32)
        self.presses = presses
        self.mm = mm_per_px
        self.gel = gel
        self.shading = shading
        h, w = background.shape[:2]
        self.position_scale_mm = 0.5 * max(h, w) * mm_per_px
        mean = self.bg.reshape(-1, 3).mean(axis=0)
        self.reference = (float(mean[0]), float(mean[1]), float(mean[2]))
        zero = LightModel(np.zeros((3, TABLE_BINS, TABLE_BINS), np.float32), 0.0, shading, self.reference)
        profile = provisional_profile(background, mm_per_px, gel, zero)
        self.render = {r: PressRender(profile, sphere(2 * r)) for r in sorted({p.ball_radius_mm for p in presses})}
        self.shade = self.bg / np.asarray(self.reference, np.float32) if shading == "multiplicative" else None
        self.notes: list[str] = []
        self.crease = 0.0  # the tables' crease penalty near the flat normal (light_fit.crease_choice)
        self.sink_table = False  # whether the light has the sink table (light_sink_table.sink_table_choice)

    # -- contacts -------------------------------------------------------------------------------
    def pose(self, p: Press, c: Contact) -> Pose:
        return self.render[p.ball_radius_mm].pose_of_pixel(c.centre_x_px, c.centre_y_px, -float(c.depth_mm or 0.0))

    def max_depth(self, p: Press) -> float:
        limit = self.gel.thickness_mm if math.isfinite(self.gel.thickness_mm) else p.ball_radius_mm
        return 0.98 * min(p.ball_radius_mm, limit)

    def contact_radius_px(self, p: Press, c: Contact) -> float:
        result = self.render[p.ball_radius_mm].solve(self.pose(p, c), fields=frozenset())
        area = result.normal.contact_area_mm2 if result.normal is not None else 0.0
        return math.sqrt(area / math.pi) / self.mm

    def depth_for_radius(self, p: Press, c: Contact, radius_px: float) -> float:
        """The depth at which the solver's contact radius is ``radius_px`` (bisection)."""
        lo, hi = 0.0, self.max_depth(p)
        for _ in range(24):
            mid = 0.5 * (lo + hi)
            if self.contact_radius_px(p, Contact(c.centre_x_px, c.centre_y_px, 0.0, mid)) < radius_px:
                lo = mid
            else:
                hi = mid
            if hi - lo < 1e-4:
                break
        return 0.5 * (lo + hi)

    def start(self, p: Press) -> Contact:
        if p.given:
            assert p.centre_px is not None and p.radius_px is not None
            c = Contact(float(p.centre_px[0]), float(p.centre_px[1]), float(p.radius_px))
        else:
            found = find_contact(self.background, p.image)
            cx, cy = p.centre_px or (found.centre_x_px, found.centre_y_px)
            c = Contact(float(cx), float(cy), float(p.radius_px or found.radius_px))
        depth = p.depth_mm if (p.depth_mm is not None and not p.given) else self.depth_for_radius(p, c, c.radius_px)
        deepest = self.max_depth(p)
        depth = min(max(float(depth), 1e-3), deepest)
        if p.given and depth >= deepest - 1e-3:  # used as given, never refined: say it is not reachable
            widest = self.contact_radius_px(p, Contact(c.centre_x_px, c.centre_y_px, 0.0, deepest))
            if widest < c.radius_px - 0.5:
                self.notes.append(
                    f"{p.name or 'a press'}: its given contact radius ({c.radius_px:g} px) is wider than the ball "
                    f"makes at the deepest press allowed ({widest:.1f} px at {deepest:.2f} mm), so it is "
                    "placed at that depth: check --mm-per-px, --ball-radius-mm and the radius"
                )
        return Contact(c.centre_x_px, c.centre_y_px, c.radius_px, depth)

    # -- what the light is fitted on --------------------------------------------------------------
    def window(self, c: Contact, radii: float, margin_px: int) -> tuple[slice, slice]:
        h, w = self.bg.shape[:2]
        half = int(radii * c.radius_px) + margin_px
        x, y = int(round(c.centre_x_px)), int(round(c.centre_y_px))
        return slice(max(y - half, 0), min(y + half, h)), slice(max(x - half, 0), min(x + half, w))

    def samples(self, p: Press, c: Contact, sink: np.ndarray, blur_mm: float, weighted: bool = True) -> PressSamples:
        """The press's fitted pixels; ``weighted``: the centre weighs more (CENTRE_WEIGHT_*), else all alike."""
        win = self.window(c, FIT_RADII, int(4 * blur_mm / self.mm) + 4)
        probe = LightModel(np.zeros((3, 3, 3), np.float32), blur_mm)
        s = sink[win]
        gx, gy = probe.slopes(-s, self.mm)
        rows, cols = np.mgrid[win[0], win[1]]
        inside = np.hypot(cols - c.centre_x_px, rows - c.centre_y_px) < FIT_RADII * c.radius_px
        sub = np.zeros_like(inside)
        sub[::SAMPLE_STEP, ::SAMPLE_STEP] = True
        inside &= sub
        idx, wt = normal_lookup(gx[inside], gy[inside], TABLE_BINS)
        h, w = self.bg.shape[:2]
        x = (cols[inside] - (w - 1) / 2) * self.mm / self.position_scale_mm
        y = (rows[inside] - (h - 1) / 2) * self.mm / self.position_scale_mm
        bg = self.bg[win][inside]
        shade = self.shade[win][inside] if self.shade is not None else np.ones_like(bg)
        target = p.image[win].astype(np.float32)[inside] - bg
        d = np.hypot(cols[inside] - c.centre_x_px, rows[inside] - c.centre_y_px) / c.radius_px
        weight = np.maximum(d, CENTRE_WEIGHT_RADII) ** -CENTRE_WEIGHT_POWER if weighted else np.ones_like(d)
        weight /= weight.mean()
        sink_in = s[inside].astype(np.float64)
        return PressSamples(
            idx, wt.astype(np.float64), x, y, sink_in, shade, target, d < NEAR_RADII, weight, centre=d < CENTRE_RADII
        )

    def light(self, contacts: list[Contact], sinks: list[np.ndarray], blur_mm: float, order: OrderChoice) -> LightModel:
        samples = [self.samples(p, c, s, blur_mm) for p, c, s in zip(self.presses, contacts, sinks)]

        def fit_terms(fitted: list[PressSamples]):
            return fit_light_terms(fitted, TABLE_BINS, order.order, order.position_ridge, self.crease)

        sink_table = None
        if self.sink_table:
            terms, sink_table = fit_alternating(samples, fit_terms, TABLE_BINS, self.crease)
        else:
            terms = fit_terms(samples)
        return LightModel(
            terms.table.astype(np.float32),
            float(blur_mm),
            self.shading,
            self.reference,
            position_bgr=None if terms.position is None else terms.position.astype(np.float32),
            sink_bgr=terms.sink.astype(np.float32),
            position_scale_mm=self.position_scale_mm,
            position_range=self.position_range(contacts),
            sink_max_mm=max(float(s.sink.max()) for s in samples),
            sink_table_bgr=None if sink_table is None else sink_table.astype(np.float32),
        )

    def blur(self, contacts: list[Contact], sinks: list[np.ndarray]) -> float:
        """The optical blur with the smallest leave-one-press-out absolute error (table and sink terms,
        every pixel alike: the centre's weight chooses a blur at the top of the range, which smooths the rims
        away; one press: in-sample), by golden-section search over [0, BLUR_MAX_MM]."""

        def rms(blur_mm: float) -> float:
            samples = [self.samples(p, c, s, blur_mm, weighted=False) for p, c, s in zip(self.presses, contacts, sinks)]
            return held_out_mae(samples, TABLE_BINS)

        ratio = (math.sqrt(5) - 1) / 2
        lo, hi = 0.0, BLUR_MAX_MM
        a, b = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
        fa, fb = rms(a), rms(b)
        for _ in range(BLUR_STEPS):
            if fa <= fb:
                hi, b, fb = b, a, fa
                a = hi - ratio * (hi - lo)
                fa = rms(a)
            else:
                lo, a, fa = a, b, fb
                b = lo + ratio * (hi - lo)
                fb = rms(b)
        best = round(a if fa <= fb else b, 3)
        edges = {0.0: rms(0.0), BLUR_MAX_MM: rms(BLUR_MAX_MM)}
        edge = min(edges, key=lambda k: edges[k])
        if edges[edge] < min(fa, fb):
            best = edge
        if best in (0.0, BLUR_MAX_MM) or best <= 0.01 or best >= BLUR_MAX_MM - 0.01:
            side = "lower" if best < BLUR_MAX_MM / 2 else "upper"
            self.notes.append(
                f"blur {best:g} mm is at the {side} end of its range [0, {BLUR_MAX_MM:g}] mm: "
                + (
                    "the edges are as sharp as the mechanics grid draws them"
                    if side == "lower"
                    else "the frames are blurrier than the range allows: check --mm-per-px and the focus"
                )
            )
        return best

    def spread(self, contacts: list[Contact]) -> bool:
        """Whether the presses span enough of the field for position terms (MIN_POSITION_PRESSES or
        more, their centres over at least MIN_SPAN of the frame's width or of its height); if not,
        a note says so and the light is the same everywhere but for the background's shading.
        Beyond the span the presses covered, the terms are held at its edge (``position_range``)."""
        h, w = self.bg.shape[:2]
        xs = [c.centre_x_px for c in contacts]
        ys = [c.centre_y_px for c in contacts]
        span_x, span_y = (max(xs) - min(xs)) / w, (max(ys) - min(ys)) / h
        if len(contacts) >= MIN_POSITION_PRESSES and max(span_x, span_y) >= MIN_SPAN:
            return True
        self.notes.append(
            f"the presses span {span_x:.0%} of the frame's width and {span_y:.0%} of its height "
            f"({len(contacts)} presses): the light's change across the field needs {MIN_POSITION_PRESSES} or more "
            f"spanning {MIN_SPAN:.0%} of either, so it is taken as the same everywhere (shaded by the background)"
        )
        return False

    def order(self, samples: list[PressSamples]) -> OrderChoice:
        """The position terms' order and ridge: by leaving each press out (``choose_order``) from
        MIN_CHOICE_PRESSES presses; with fewer (two left when one is out: too few to judge a change
        across the field), the terms with the stronger of the ridges, and a note says so."""
        if len(samples) >= MIN_CHOICE_PRESSES:
            return choose_order(samples, TABLE_BINS, self.crease)
        ridge = max(POSITION_RIDGES)
        self.notes.append(
            f"{len(samples)} presses: too few to check the light's change across the field by leaving one out; "
            f"fitted with the stronger ridge ({ridge:g}) and held at the presses' span beyond it"
        )
        return OrderChoice(1, ridge, {})

    def position_range(self, contacts: list[Contact]) -> tuple[float, float, float, float]:
        """(x̃ low, x̃ high, ỹ low, ỹ high) the presses covered (centres ± contact radii)."""
        h, w = self.bg.shape[:2]
        k = self.mm / self.position_scale_mm
        xs = [(c.centre_x_px + sign * c.radius_px - (w - 1) / 2) * k for c in contacts for sign in (-1, 1)]
        ys = [(c.centre_y_px + sign * c.radius_px - (h - 1) / 2) * k for c in contacts for sign in (-1, 1)]
        return (min(xs), max(xs), min(ys), max(ys))

    def sinks(self, contacts: list[Contact]) -> list[np.ndarray]:
        return [self.render[p.ball_radius_mm].sink_mm(self.pose(p, c)) for p, c in zip(self.presses, contacts)]

    # -- refinement under a light ---------------------------------------------------------------
    def refine(self, light: LightModel, p: Press, c: Contact) -> Contact:
        """The centre and depth whose rendered press best matches ``p`` under ``light``: Gauss–Newton
        with finite differences on a window, robust (L1-like) weights."""
        from sensor_sim.light import FramePlanes

        h, w = self.bg.shape[:2]
        planes = self._planes(light)
        win = self.window(c, FIT_RADII + 0.5, int(4 * light.blur_mm / self.mm) + 8)
        real = p.image[win].astype(np.float32)[::SAMPLE_STEP, ::SAMPLE_STEP]
        bg = self.bg[win][::SAMPLE_STEP, ::SAMPLE_STEP]

        def crop(a):
            return None if a is None else a[:, win[0], win[1]]

        local = FramePlanes(
            crop(planes.scale),
            crop(planes.x),
            crop(planes.y),
            planes.position,
            crop(planes.sink),
            crop(planes.sink2),
            planes.sink_table,
        )

        def sink_at(theta: np.ndarray) -> np.ndarray:
            cc = Contact(theta[0], theta[1], c.radius_px, theta[2])
            return self.render[p.ball_radius_mm].sink_mm(self.pose(p, cc))[win]

        def residual(sink: np.ndarray) -> np.ndarray:
            gx, gy = light.slopes(-sink, self.mm)
            change = light.change_frame(gx, gy, sink, local)
            rendered = bg + np.moveaxis(change, 0, -1)[::SAMPLE_STEP, ::SAMPLE_STEP]
            return (rendered - real).ravel()

        def moved(sink: np.ndarray, dx: float, dy: float) -> np.ndarray:
            """The same press moved by (dx, dy) px: the gel is the same everywhere, so its sink moves
            with it (a solve saved per derivative)."""
            shift = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])
            return cv2.warpAffine(sink, shift, sink.shape[::-1], flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)

        theta = np.array([c.centre_x_px, c.centre_y_px, float(c.depth_mm or 0.0)])
        top = self.max_depth(p)
        sink = sink_at(theta)
        r = residual(sink)
        for _ in range(REFINE_ITERATIONS):
            deeper = theta + np.array([0.0, 0.0, DEPTH_STEP_MM])
            J = np.stack(
                [
                    (residual(moved(sink, CENTRE_STEP_PX, 0.0)) - r) / CENTRE_STEP_PX,
                    (residual(moved(sink, 0.0, CENTRE_STEP_PX)) - r) / CENTRE_STEP_PX,
                    (residual(sink_at(deeper)) - r) / DEPTH_STEP_MM,
                ],
                axis=1,
            )
            weight = 1.0 / np.maximum(np.abs(r), 2.0)  # robust: a blemish on the gel pulls no harder than noise
            JW = J * weight[:, None]
            delta = np.linalg.lstsq(JW.T @ J + 1e-6 * np.eye(3), -JW.T @ r, rcond=None)[0]
            delta = np.clip(delta, [-3.0, -3.0, -0.1], [3.0, 3.0, 0.1])  # trust region: px, px, mm
            trial = theta + delta
            trial[2] = min(max(trial[2], 1e-3), top)
            sink_trial = sink_at(trial)
            r_trial = residual(sink_trial)
            if np.abs(r_trial).mean() > np.abs(r).mean():
                break
            theta, r, sink = trial, r_trial, sink_trial
            if abs(delta[0]) < 0.05 and abs(delta[1]) < 0.05 and abs(delta[2]) < 1e-3:
                break
        depth = float(theta[2])
        if depth >= top - 1e-6:
            self.notes.append(
                f"{p.name or 'a press'}: the fitted depth reached its limit ({top:.2f} mm: the ball's radius or "
                "the gel's thickness): check --ball-radius-mm and --gel-thickness-mm"
            )
        refined = Contact(float(theta[0]), float(theta[1]), c.radius_px, depth)
        return Contact(refined.centre_x_px, refined.centre_y_px, self.contact_radius_px(p, refined), depth)

    def _planes(self, light: LightModel):
        h, w = self.bg.shape[:2]
        return light.frame_planes(self.bg, w * self.mm, h * self.mm)
