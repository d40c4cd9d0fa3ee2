"""What the sensor's camera sees: the deformed gel rendered for three sensor kinds.

- ``rgb``: three coloured lights; the colour change per channel is a quadratic in
  the surface slope, fitted to real GelSight Mini presses (bench/calibrate_optics.py).
- ``rgb_markers``: the same with a printed marker grid.
- ``white_markers``: white light: a grey, slope-darkened image with markers.

Markers move with the tangential surface displacement of the gel. A background
(the real GelSight Mini no-contact frame by default, or one you supply), optical
blur, vignetting for synthetic backgrounds, and sensor noise complete the frame.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from scipy.ndimage import map_coordinates

from rig.sim.tactile.contact import SensorGeometry

SENSOR_KINDS = ("rgb", "rgb_markers", "white_markers")
DATA = Path(__file__).parent / "data"


@functools.lru_cache(maxsize=1)
def calibration() -> dict:
    return json.loads((DATA / "optics_calibration.json").read_text())


@functools.lru_cache(maxsize=4)
def real_background(height: int, width: int) -> np.ndarray:
    img = cv2.imread(str(DATA / "gelsight_mini_background.png"), cv2.IMREAD_COLOR)
    return cv2.resize(img, (width, height), interpolation=cv2.INTER_AREA).astype(np.float32)


@dataclass(frozen=True)
class OpticsSpec:
    kind: str = "rgb"
    height_px: int = 256
    width_px: int = 256
    noise_std: float = 1.0  # grey levels, per pixel and channel
    marker_pitch_mm: float = 0.7  # 20 × 20 markers on a 14 mm pad; the metric uses the central 18 × 18
    marker_radius_mm: float = 0.17
    marker_darkness: float = 0.8
    vignetting: float = 0.3  # edge darkening of synthetic (white-light) backgrounds

    def __post_init__(self):
        if self.kind not in SENSOR_KINDS:
            raise ValueError(f"sensor kind must be one of {', '.join(SENSOR_KINDS)}, got {self.kind!r}")

    @property
    def has_markers(self) -> bool:
        return self.kind.endswith("_markers")


class Renderer:
    def __init__(self, spec: OpticsSpec | None = None, geometry: SensorGeometry | None = None,
                 background: np.ndarray | None = None, seed: int = 0):
        self.spec = spec or OpticsSpec()
        self.geometry = geometry or SensorGeometry()
        h, w = self.spec.height_px, self.spec.width_px
        self.mm_per_px = self.geometry.width_mm / w
        cal = calibration()
        self.coef = np.asarray(cal["coefficients_bgr"], dtype=np.float32).T  # (5, 3)
        self.blur_px = cal["blur_mm"] / self.mm_per_px
        if background is not None:
            self.background = cv2.resize(background, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)
        elif self.spec.kind == "white_markers":
            yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
            r2 = ((xx - (w - 1) / 2) ** 2 + (yy - (h - 1) / 2) ** 2) / (0.5 * max(h, w)) ** 2
            grey = 200.0 * (1.0 - self.spec.vignetting * r2)
            self.background = np.repeat(grey[..., None], 3, axis=2)
        else:
            self.background = real_background(h, w)
        self._rng = np.random.default_rng(seed)
        # Sensor noise from a bank of precomputed fields, shifted at random per frame:
        # statistically the same per pixel, ~10x cheaper than fresh Gaussian draws.
        self._noise = (self._rng.normal(0.0, self.spec.noise_std, (4, h, w, 3)).astype(np.float32)
                       if self.spec.noise_std > 0 else None)
        pitch = self.spec.marker_pitch_mm
        n_x = int(self.geometry.width_mm / pitch)
        n_y = int(self.geometry.height_mm / pitch)
        mx = (np.arange(n_x) - (n_x - 1) / 2) * pitch
        my = (np.arange(n_y) - (n_y - 1) / 2) * pitch
        self.marker_rest_mm = np.stack(np.meshgrid(mx, my), axis=-1).reshape(-1, 2)  # (x, y), +y up

    def needs(self) -> frozenset[str]:
        """The displacement fields this sensor kind needs from the mechanics."""
        return frozenset({"uz", "uxy"}) if self.spec.has_markers else frozenset({"uz"})

    def _on_image(self, field: np.ndarray) -> np.ndarray:
        return cv2.resize(field.astype(np.float32), (self.spec.width_px, self.spec.height_px),
                          interpolation=cv2.INTER_CUBIC)

    def slope_change(self, uz_mm: np.ndarray) -> np.ndarray:
        """(H, W, 3) colour change for the surface sink ``uz_mm`` (mechanics grid)."""
        z = -self._on_image(uz_mm)
        gy, gx = np.gradient(z, np.float32(self.mm_per_px))
        gx = cv2.GaussianBlur(gx, (0, 0), self.blur_px)
        gy = cv2.GaussianBlur(gy, (0, 0), self.blur_px)
        if self.spec.kind == "white_markers":
            # A diffuse white ring light: the directional (colour) terms cancel and a
            # tilted surface sends less light to the camera; the gain per unit slope is
            # the calibrated colour response's mean magnitude.
            gain = float(np.mean(np.hypot(self.coef[0], self.coef[1])))
            change = -gain * np.hypot(gx, gy)
            return np.repeat(change[..., None], 3, axis=2)
        gxx, gyy, gxy = gx * gx, gy * gy, gx * gy
        c = self.coef
        return np.stack([c[0, ch] * gx + c[1, ch] * gy + c[2, ch] * gxx + c[3, ch] * gyy + c[4, ch] * gxy
                         for ch in range(3)], axis=-1)

    def marker_positions_px(self, ux_mm: np.ndarray | None, uy_mm: np.ndarray | None) -> np.ndarray:
        """(n, 2) marker centres (col, row) in pixels, displaced with the gel surface."""
        h, w = self.spec.height_px, self.spec.width_px
        xy = self.marker_rest_mm.copy()
        if ux_mm is not None and (np.any(ux_mm) or np.any(uy_mm)):
            ny, nx = ux_mm.shape
            dx = self.geometry.dx_mm
            cols = xy[:, 0] / dx + (nx - 1) / 2
            rows = (ny - 1) / 2 - xy[:, 1] / dx
            coords = np.stack([rows, cols])
            xy[:, 0] += map_coordinates(ux_mm, coords, order=1, mode="nearest")
            xy[:, 1] += map_coordinates(uy_mm, coords, order=1, mode="nearest")
        col = xy[:, 0] / self.mm_per_px + (w - 1) / 2
        row = (h - 1) / 2 - xy[:, 1] / self.mm_per_px
        return np.stack([col, row], axis=-1)

    def _marker_mask(self, centres_px: np.ndarray) -> np.ndarray:
        h, w = self.spec.height_px, self.spec.width_px
        shift = 4  # sub-pixel precision: 1/16 px
        mask = np.zeros((h, w), np.float32)
        radius = int(round(self.spec.marker_radius_mm / self.mm_per_px * (1 << shift)))
        for c, r in centres_px:
            cv2.circle(mask, (int(round(c * (1 << shift))), int(round(r * (1 << shift)))), radius, 1.0, -1,
                       cv2.LINE_AA, shift)
        return cv2.GaussianBlur(mask, (0, 0), 0.6)

    def render(self, fields: dict[str, np.ndarray]) -> np.ndarray:
        """BGR uint8 frame from the mechanics fields ("uz"; "ux", "uy" for markers)."""
        img = self.background.copy()
        uz = fields.get("uz")
        if uz is not None and np.any(uz):
            img += self.slope_change(uz)
        if self.spec.has_markers:
            centres = self.marker_positions_px(fields.get("ux"), fields.get("uy"))
            img *= 1.0 - self.spec.marker_darkness * self._marker_mask(centres)[..., None]
        if self._noise is not None:
            k = int(self._rng.integers(len(self._noise)))
            dy, dx = (int(v) for v in self._rng.integers(0, img.shape[:2]))
            img += np.roll(self._noise[k], (dy, dx), axis=(0, 1))
        return np.clip(img, 0, 255).astype(np.uint8)
