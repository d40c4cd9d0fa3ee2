"""What a calibration hands a person: errors beside the background's, a contact sheet, the field's
coverage, the noise, a profile.

    renders = rendered_presses(background, presses, fit, mm_per_px, gel)  # each press through PressRender
    scores = press_scores(background, presses, fit.contacts, renders)       # fit and background-only MAE
    sheet = contact_sheet(presses, fit.contacts, renders, scores)           # real | rendered | difference
    coverage = field_coverage(fit.contacts, background.shape)               # where presses are missing
    noise = estimate_noise(background, presses, fit.contacts)               # the camera's SensorNoise
    profile = profile_from_fit(background, fit, mm_per_px, name="my_sensor", ...)

numpy/cv2 only; the command that prints and writes these is ``rig sensor calibrate``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from sensor_sim.calibration import CalibrationError, CalibrationResult, Contact, Press, provisional_profile
from sensor_sim.elastomer import Elastomer
from sensor_sim.noise import NoiseStats, SensorNoise, difference_stats, noise_from_stats
from sensor_sim.profile import SensorProfile

NEAR_RADII = 1.5  # "near the contact": within this many contact radii of its centre
TILE_PX = 200  # contact-sheet tile side
SHEET_RADII = 3.0  # a tile shows this many contact radii either side of the centre
DIFF_GAIN = 4.0  # the difference tile: |real - rendered| summed over channels, ×4, as a heat map
NOISE_FAR_RADII = 4.0  # the noise is measured this many contact radii and more from every contact
REGIONS = ("top-left", "top", "top-right", "left", "centre", "right", "bottom-left", "bottom", "bottom-right")
# What a region without a press costs, measured (bench/optics_bench.py, docs/benchmarks.md): near the
# contact, the error relative to the background's for presses spread over the field and for presses
# in one quadrant only (the others then rendered from the light's extrapolation).
SPREAD_RATIO, ONE_QUADRANT_RATIO = "18-19 %", "23-30 %"


@dataclass(frozen=True)
class PressScore:
    name: str
    contact: Contact
    mae: float  # 0–255, all channels, whole frame
    mae_near: float  # within NEAR_RADII contact radii
    background_mae: float  # the no-contact frame alone, whole frame
    background_mae_near: float


def fitted_profile(background: np.ndarray, fit: CalibrationResult, mm_per_px: float, gel: Elastomer) -> SensorProfile:
    """The frames' own profile (their size and scale) with the fitted light and no noise."""
    return provisional_profile(background, mm_per_px, gel, fit.light)


def rendered_presses(
    background: np.ndarray, presses: list[Press], fit: CalibrationResult, mm_per_px: float, gel: Elastomer
) -> list[np.ndarray]:
    """Each press rendered at its fitted contact through ``PressRender`` (the solver and renderer of
    the simulated rig), at the frames' resolution, without noise: (H, W, 3) uint8 per press."""
    from objects.indenters import sphere
    from sensor_sim.press_render import PressRender

    profile = fitted_profile(background, fit, mm_per_px, gel)
    by_ball = {r: PressRender(profile, sphere(2 * r)) for r in {p.ball_radius_mm for p in presses}}
    out = []
    for p, c in zip(presses, fit.contacts):
        press = by_ball[p.ball_radius_mm]
        out.append(press.render(press.pose_of_pixel(c.centre_x_px, c.centre_y_px, -float(c.depth_mm or 0.0))))
    return out


def _near(shape: tuple[int, ...], contact: Contact) -> np.ndarray:
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]]
    return np.hypot(xs - contact.centre_x_px, ys - contact.centre_y_px) < NEAR_RADII * contact.radius_px


def press_scores(
    background: np.ndarray, presses: list[Press], contacts: list[Contact], renders: list[np.ndarray]
) -> list[PressScore]:
    """Per press: the render's MAE and the background-only baseline's, whole frame and near the contact."""
    bg = background.astype(np.float32)
    scores = []
    for i, (press, contact, rendered) in enumerate(zip(presses, contacts, renders)):
        real = press.image.astype(np.float32)
        near = _near(real.shape, contact)
        err, base = np.abs(rendered.astype(np.float32) - real), np.abs(bg - real)
        scores.append(
            PressScore(
                press.name or f"press {i}",
                contact,
                float(err.mean()),
                float(err[near].mean()),
                float(base.mean()),
                float(base[near].mean()),
            )
        )
    return scores


def _tile(img: np.ndarray, contact: Contact) -> np.ndarray:
    """A square crop of ``img`` around the contact (padded at the frame's edge), TILE_PX square."""
    half = max(int(SHEET_RADII * contact.radius_px), 16)
    cx, cy = int(round(contact.centre_x_px)), int(round(contact.centre_y_px))
    padded = cv2.copyMakeBorder(img, half, half, half, half, cv2.BORDER_CONSTANT, value=(0, 0, 0))
    crop = padded[cy : cy + 2 * half, cx : cx + 2 * half]
    return cv2.resize(crop, (TILE_PX, TILE_PX), interpolation=cv2.INTER_AREA)


def _label(width: int, text: str, height: int = 22) -> np.ndarray:
    strip = np.full((height, width, 3), 255, np.uint8)
    cv2.putText(strip, text, (4, height - 7), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return strip


def sheet_row(real: np.ndarray, rendered: np.ndarray, contact: Contact, caption: str) -> np.ndarray:
    """One press: a caption over real (the contact drawn as a thin circle) | rendered | |difference| ×4."""
    diff = np.abs(rendered.astype(np.float32) - real.astype(np.float32)).sum(axis=2) * (DIFF_GAIN / 3)
    heat = cv2.applyColorMap(np.clip(diff, 0, 255).astype(np.uint8), cv2.COLORMAP_INFERNO)
    tile_real = _tile(real, contact)
    scale = TILE_PX / (2 * max(int(SHEET_RADII * contact.radius_px), 16))
    centre = TILE_PX // 2
    cv2.circle(tile_real, (centre, centre), int(round(contact.radius_px * scale)), (0, 255, 0), 1, cv2.LINE_AA)
    return np.vstack(
        [_label(3 * TILE_PX, caption), np.hstack([tile_real, _tile(rendered, contact), _tile(heat, contact)])]
    )


def sheet_header() -> np.ndarray:
    return np.hstack(
        [_label(TILE_PX, "real (contact found)"), _label(TILE_PX, "rendered"), _label(TILE_PX, "|difference| x4")]
    )


def contact_sheet(
    presses: list[Press], contacts: list[Contact], renders: list[np.ndarray], scores: list[PressScore]
) -> np.ndarray:
    """BGR image: one row per press, real | rendered | difference (heat map, ×DIFF_GAIN), cropped to
    SHEET_RADII contact radii around the contact found."""
    rows = [sheet_header()]
    for press, contact, rendered, score in zip(presses, contacts, renders, scores):
        caption = (
            f"{score.name}: MAE {score.mae:.2f} whole / {score.mae_near:.2f} near "
            f"(background {score.background_mae:.2f} / {score.background_mae_near:.2f})"
        )
        rows.append(sheet_row(press.image, rendered, contact, caption))
    return np.vstack(rows)


@dataclass(frozen=True)
class Coverage:
    covered: tuple[str, ...]  # the regions (of a 3 × 3 split of the frame) with a press centre in them
    missing: tuple[str, ...]

    def lines(self, left_out_ratio: float | None = None) -> list[str]:
        """What a person reads: where presses are, where they are missing and what that costs: ``left_out_ratio``,
        this calibration's near error on presses left out (``calibration_check``), else the bench's range."""
        if not self.missing:
            return [f"field coverage: presses in all {len(REGIONS)} regions of the frame"]
        cost = (
            f"presses left out of this calibration render at {left_out_ratio:.0%} of the background's error near "
            "the contact, presses in a region none showed worse still"
            if left_out_ratio is not None
            else f"presses spread over the field render at {SPREAD_RATIO} of the background's error, presses in one "
            f"quadrant only at {ONE_QUADRANT_RATIO} elsewhere (docs/benchmarks.md, the simulated sensor against real "
            "frames)"
        )
        return [
            f"field coverage: presses in {len(self.covered)} of {len(REGIONS)} regions ({', '.join(self.covered)}); "
            f"none in {', '.join(self.missing)}",
            f"  there the light is held at what the nearest presses showed: {cost}; a press in each missing region "
            "closes that gap",
        ]


def region_of(x_px: float, y_px: float, shape: tuple[int, ...]) -> str:
    h, w = shape[:2]
    col = min(2, max(0, int(3 * x_px / w)))
    row = min(2, max(0, int(3 * y_px / h)))
    return REGIONS[3 * row + col]


def field_coverage(contacts: list[Contact], shape: tuple[int, ...]) -> Coverage:
    seen = {region_of(c.centre_x_px, c.centre_y_px, shape) for c in contacts}
    return Coverage(tuple(r for r in REGIONS if r in seen), tuple(r for r in REGIONS if r not in seen))


def noise_stats(background: np.ndarray, presses: list[Press], contacts: list[Contact]) -> NoiseStats:
    """The noise statistics of the presses' differences to the background, NOISE_FAR_RADII contact
    radii and more away from every contact, averaged over the presses (weighted by pixels)."""
    h, w = background.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    parts = []
    for press, c in zip(presses, contacts):
        far = np.hypot(xs - c.centre_x_px, ys - c.centre_y_px) > NOISE_FAR_RADII * c.radius_px
        try:
            parts.append(difference_stats(press.image, background, far))
        except ValueError:
            continue  # a press that fills the frame: no noise to see beside it
    if not parts:
        raise CalibrationError("no part of any press frame is far enough from its contact to measure the noise")
    weight = np.array([p.pixels for p in parts], float)
    weight /= weight.sum()

    def mean(values) -> tuple[float, ...]:
        return tuple(float(v) for v in np.average(np.asarray(values, float), axis=0, weights=weight).reshape(-1))

    return NoiseStats(
        mean([p.std_bgr for p in parts]),  # type: ignore[arg-type]
        mean([p.neighbour_correlation for p in parts])[0],
        mean([p.channel_correlation for p in parts]),  # type: ignore[arg-type]
        int(sum(p.pixels for p in parts)),
    )


def estimate_noise(background: np.ndarray, presses: list[Press], contacts: list[Contact]) -> SensorNoise:
    """The camera's noise (``SensorNoise``, at the frames' pixels) from the presses away from the contact:
    the model whose two frames give the measured statistics (sensor_sim/noise.py)."""
    return noise_from_stats(noise_stats(background, presses, contacts))


def field(
    background: np.ndarray, mm_per_px: float, field_mm: tuple[float, float] | None
) -> tuple[np.ndarray, float, float]:
    """The centred part of ``background`` the simulator renders (``field_mm`` (width, height), default
    the whole frame: cropped to the nearest whole pixels) and its width and height in mm.
    CalibrationError if it does not fit."""
    h, w = background.shape[:2]
    if field_mm is None:
        return background.copy(), w * mm_per_px, h * mm_per_px
    fw, fh = (int(round(v / mm_per_px)) for v in field_mm)
    if not (16 <= fw <= w and 16 <= fh <= h):
        raise CalibrationError(
            f"field_mm {field_mm[0]:g} x {field_mm[1]:g} is {fw}x{fh} px at {mm_per_px} mm/px; the frame ({w}x{h}) "
            f"holds 16 to {w} x 16 to {h} px"
        )
    y0, x0 = (h - fh) // 2, (w - fw) // 2
    return background[y0 : y0 + fh, x0 : x0 + fw].copy(), float(field_mm[0]), float(field_mm[1])


def profile_from_fit(
    background: np.ndarray,
    fit: CalibrationResult,
    mm_per_px: float,
    *,
    name: str,
    source: str,
    noise: SensorNoise,
    gel: Elastomer,
    frame_width_px: int | None = None,
    field_mm: tuple[float, float] | None = None,
) -> SensorProfile:
    """The profile of the sensor: the fitted light, the background cropped to the field (whole frame by
    default; kept at the camera's resolution, which the renderer resizes), rendered ``frame_width_px``
    wide (default: the camera's own pixels; the height keeps the field's aspect)."""
    crop, width_mm, height_mm = field(background, mm_per_px, field_mm)
    ch, cw = crop.shape[:2]
    width_px = frame_width_px or cw
    height_px = max(16, int(round(width_px * ch / cw)))
    return SensorProfile(
        name=name,
        source=source,
        width_px=width_px,
        height_px=height_px,
        mm_per_px=width_mm / width_px,
        gel_thickness_mm=gel.thickness_mm,
        gel_E_MPa=gel.E_MPa,
        noise=noise,
        light=fit.light,
        background=crop,
        format=fit.light.profile_format,  # 4: the quadratic sink field; 5: the sink table
    )


def mean_scores(scores: list[PressScore]) -> tuple[float, float, float, float]:
    """(fit whole, fit near, background whole, background near), each a mean over the presses."""
    keys = ("mae", "mae_near", "background_mae", "background_mae_near")
    fit, fit_near, base, base_near = (sum(getattr(s, k) for s in scores) / len(scores) for k in keys)
    return fit, fit_near, base, base_near
