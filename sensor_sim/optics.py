"""What the sensor's camera sees: the deformed gel rendered for three sensor kinds.

- ``rgb``: coloured lights from the sides; the colour change is looked up from the
  surface normal in a bounded table (``LightModel``), fitted to real presses by
  ``sensor_sim.calibration.fit_optics`` and shipped in the sensor profile.
- ``rgb_markers``: the same with a printed marker grid.
- ``white_markers``: white light: a grey image darkened where the gel tilts, with markers.

Markers move with the tangential surface displacement of the gel. The profile's
background (the real GelSight Mini no-contact frame by default, or one you supply),
optical blur, vignetting for synthetic backgrounds and sensor noise complete the frame.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.ndimage import map_coordinates

from sensor_sim.contact import SensorGeometry
from sensor_sim.light import LightModel, OpticsSpec, soft_bound
from sensor_sim.profile import default_profile


class Renderer:
    """Renders mechanics fields into frames with a sensor profile's optics.

    ``light`` and ``background`` default to the profile's (the shipped GelSight Mini
    profile unless ``profile`` is given); ``background`` (any size, BGR) overrides it.
    """

    def __init__(
        self,
        spec: OpticsSpec | None = None,
        geometry: SensorGeometry | None = None,
        background: np.ndarray | None = None,
        seed: int = 0,
        *,
        profile=None,
    ):
        profile = profile or default_profile()
        self.spec = spec or OpticsSpec()
        self.geometry = geometry or SensorGeometry()
        self.light: LightModel = profile.light
        h, w = self.spec.height_px, self.spec.width_px
        self.mm_per_px = self.geometry.width_mm / w
        if background is None and self.spec.kind != "white_markers":
            background = profile.background
        if background is not None:
            self.background = cv2.resize(background, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)
        else:
            yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
            r2 = ((xx - (w - 1) / 2) ** 2 + (yy - (h - 1) / 2) ** 2) / (0.5 * max(h, w)) ** 2
            grey = 200.0 * (1.0 - self.spec.vignetting * r2)
            self.background = np.repeat(grey[..., None], 3, axis=2)
        # White light: a tilted surface sends less light to the camera, with the same
        # small-tilt gain as the coloured response's mean magnitude, and never below black.
        self.white_darkening = min(0.9, self.light.slope_gain() / 200.0)
        self._rng = np.random.default_rng(seed)
        # Sensor noise from a bank of precomputed fields, shifted at random per frame:
        # statistically the same per pixel, ~10x cheaper than fresh Gaussian draws.
        self._noise = (
            self._rng.normal(0.0, self.spec.noise_std, (4, h, w, 3)).astype(np.float32)
            if self.spec.noise_std > 0
            else None
        )
        pitch = self.spec.marker_pitch_mm
        n_x = int(self.geometry.width_mm / pitch)
        n_y = int(self.geometry.height_mm / pitch)
        mx = (np.arange(n_x) - (n_x - 1) / 2) * pitch
        my = (np.arange(n_y) - (n_y - 1) / 2) * pitch
        self.marker_rest_mm = np.stack(np.meshgrid(mx, my), axis=-1).reshape(-1, 2)  # (x, y), +y up

    @classmethod
    def from_profile(cls, profile, kind: str = "rgb", seed: int = 0) -> "Renderer":
        """A renderer for ``kind`` with everything (frame, scale, noise, markers) from ``profile``."""
        return cls(profile.optics_spec(kind), profile.geometry(), seed=seed, profile=profile)

    def needs(self) -> frozenset[str]:
        """The displacement fields this sensor kind needs from the mechanics."""
        return frozenset({"uz", "uxy"}) if self.spec.has_markers else frozenset({"uz"})

    def _on_image(self, field: np.ndarray) -> np.ndarray:
        return cv2.resize(
            field.astype(np.float32), (self.spec.width_px, self.spec.height_px), interpolation=cv2.INTER_CUBIC
        )

    def slope_change(self, uz_mm: np.ndarray) -> np.ndarray:
        """(H, W, 3) colour change for the surface sink ``uz_mm`` (mechanics grid)."""
        gx, gy = self.light.slopes(-self._on_image(uz_mm), self.mm_per_px)
        if self.spec.kind == "white_markers":
            tilt = np.sqrt(gx * gx + gy * gy) / np.sqrt(1.0 + gx * gx + gy * gy)  # sin of the tilt, in [0, 1)
            return -self.white_darkening * tilt[..., None] * self.background
        return self.light.change(gx, gy, self.background)

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
            cv2.circle(
                mask, (int(round(c * (1 << shift))), int(round(r * (1 << shift)))), radius, 1.0, -1, cv2.LINE_AA, shift
            )
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
        return np.rint(soft_bound(img)).astype(np.uint8)
