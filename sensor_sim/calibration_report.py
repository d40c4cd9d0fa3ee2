"""What a calibration hands a person: errors beside the background's, a contact sheet, a profile.

    scores = press_scores(background, presses, fit, mm_per_px)   # fit and background-only MAE per press
    sheet = contact_sheet(background, presses, fit, mm_per_px)    # real | rendered | difference per press
    profile = profile_from_fit(background, fit, mm_per_px, name="my_sensor", ...)

numpy/cv2 only; the command that prints and writes these is ``rig sensor calibrate``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from sensor_sim.calibration import CalibrationError, CalibrationResult, Contact, Press, render_press
from sensor_sim.profile import SensorProfile

NEAR_RADII = 1.5  # "near the contact": within this many contact radii of its centre
TILE_PX = 200  # contact-sheet tile side
SHEET_RADII = 3.0  # a tile shows this many contact radii either side of the centre
DIFF_GAIN = 4.0  # the difference tile: |real - rendered| summed over channels, ×4, as a heat map


@dataclass(frozen=True)
class PressScore:
    name: str
    contact: Contact
    mae: float  # 0–255, all channels, whole frame
    mae_near: float  # within NEAR_RADII contact radii
    background_mae: float  # the no-contact frame alone, whole frame
    background_mae_near: float


def _near(shape: tuple[int, ...], contact: Contact) -> np.ndarray:
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]]
    return np.hypot(xs - contact.centre_x_px, ys - contact.centre_y_px) < NEAR_RADII * contact.radius_px


def press_scores(
    background: np.ndarray, presses: list[Press], fit: CalibrationResult, mm_per_px: float
) -> list[PressScore]:
    """Per press: the fit's MAE and the background-only baseline's, whole frame and near the contact."""
    bg = background.astype(np.float32)
    scores = []
    for i, (press, contact) in enumerate(zip(presses, fit.contacts)):
        real = press.image.astype(np.float32)
        near = _near(real.shape, contact)
        rendered = np.clip(render_press(fit.light, background, contact, press.ball_radius_mm, mm_per_px), 0, 255)
        err, base = np.abs(rendered - real), np.abs(bg - real)
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


def contact_sheet(background: np.ndarray, presses: list[Press], fit: CalibrationResult, mm_per_px: float) -> np.ndarray:
    """BGR image: one row per press, real | rendered | difference (heat map, ×DIFF_GAIN), cropped to
    SHEET_RADII contact radii around the contact found (drawn as a thin circle on the real tile)."""
    rows = [
        np.hstack(
            [_label(TILE_PX, "real (found contact)"), _label(TILE_PX, "rendered"), _label(TILE_PX, "|difference| x4")]
        )
    ]
    for press, score in zip(presses, press_scores(background, presses, fit, mm_per_px)):
        c = score.contact
        rendered = np.clip(render_press(fit.light, background, c, press.ball_radius_mm, mm_per_px), 0, 255)
        diff = np.abs(rendered - press.image.astype(np.float32)).sum(axis=2) * (DIFF_GAIN / 3)
        heat = cv2.applyColorMap(np.clip(diff, 0, 255).astype(np.uint8), cv2.COLORMAP_INFERNO)
        real = _tile(press.image, c)
        scale = TILE_PX / (2 * max(int(SHEET_RADII * c.radius_px), 16))
        centre = TILE_PX // 2
        cv2.circle(real, (centre, centre), int(round(c.radius_px * scale)), (0, 255, 0), 1, cv2.LINE_AA)
        tiles = np.hstack([real, _tile(rendered.astype(np.uint8), c), _tile(heat, c)])
        caption = (
            f"{score.name}: MAE {score.mae:.2f} whole / {score.mae_near:.2f} near "
            f"(background {score.background_mae:.2f} / {score.background_mae_near:.2f})"
        )
        rows += [_label(3 * TILE_PX, caption), tiles]
    return np.vstack(rows)


def estimate_noise_std(background: np.ndarray, presses: list[Press], contacts: list[Contact]) -> float:
    """Sensor noise (grey levels per pixel and channel) from the presses' difference to the
    background away from the contact: a robust σ of the high-pass difference, over √2 (two frames)."""
    samples = []
    for press, c in zip(presses, contacts):
        diff = press.image.astype(np.float32) - background.astype(np.float32)
        high = diff - cv2.GaussianBlur(diff, (0, 0), 2.0)  # exposure drift and shading are smooth: drop them
        ys, xs = np.mgrid[0 : diff.shape[0], 0 : diff.shape[1]]
        far = np.hypot(xs - c.centre_x_px, ys - c.centre_y_px) > 4 * c.radius_px
        samples.append(high[far].ravel())
    values = np.concatenate(samples)
    mad = float(np.median(np.abs(values - np.median(values))))
    # white noise keeps ~99 % of its variance through a σ = 2 px high-pass: no correction
    return round(min(50.0, 1.4826 * mad / math.sqrt(2)), 2)


def square_field(background: np.ndarray, mm_per_px: float, field_mm: float | None) -> tuple[np.ndarray, float]:
    """The centred square of ``background`` the simulator renders (``field_mm`` wide, default the
    largest that fits) and its side in mm. CalibrationError if it does not fit."""
    h, w = background.shape[:2]
    side = min(h, w) if field_mm is None else int(round(field_mm / mm_per_px))
    if not 16 <= side <= min(h, w):
        raise CalibrationError(
            f"field_mm {field_mm} is {side} px at {mm_per_px} mm/px; the frame ({w}x{h}) holds 16 to {min(h, w)} px"
        )
    y0, x0 = (h - side) // 2, (w - side) // 2
    return background[y0 : y0 + side, x0 : x0 + side].copy(), side * mm_per_px


def profile_from_fit(
    background: np.ndarray,
    fit: CalibrationResult,
    mm_per_px: float,
    *,
    name: str,
    source: str,
    frame_px: int = 256,
    field_mm: float | None = None,
    gel_thickness_mm: float = 3.0,
    gel_E_MPa: float = 0.25,
    noise_std: float = 1.0,
) -> SensorProfile:
    """A square-field profile: the fitted optics, the background cropped to the field (kept at its
    own resolution: the renderer resizes it) and the simulator's frame of ``frame_px``."""
    crop, side_mm = square_field(background, mm_per_px, field_mm)
    return SensorProfile(
        name=name,
        source=source,
        width_px=frame_px,
        height_px=frame_px,
        mm_per_px=side_mm / frame_px,
        gel_thickness_mm=gel_thickness_mm,
        gel_E_MPa=gel_E_MPa,
        noise_std=noise_std,
        light=fit.light,
        background=crop,
    )
