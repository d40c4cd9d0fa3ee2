"""What the sensor's camera sees: the deformed gel rendered for three sensor kinds.

- ``rgb``: coloured lights from the sides; the colour change is looked up from the
  surface normal in a bounded table (``LightModel``), fitted to real presses by
  ``sensor_sim.calibration.fit_optics`` and shipped in the sensor profile.
- ``rgb_markers``: the same with a printed marker grid.
- ``white_markers``: white light: a grey image darkened where the gel tilts, with markers.

Markers move with the tangential surface displacement of the gel. The profile's
background (the real GelSight Mini no-contact frame by default, or one you supply),
optical blur, vignetting for synthetic backgrounds and sensor noise complete the frame.

The frame is built in (3, H, W) planes (contiguous per channel) from per-renderer
constants (background, shading factor, noise bank), with the same float32 operations in
the same order as the straightforward (H, W, 3) formulas, so the same uint8 frames
(tests/test_render_exact.py keeps that formulation as its reference). The last press
image and the last marker shading are kept: a slow protocol asks for the same contact,
and the same markers to 1/16 px, in consecutive frames.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.ndimage import map_coordinates

from sensor_sim.contact import SensorGeometry
from sensor_sim.light import LightModel, OpticsSpec, soft_bound_inplace
from sensor_sim.profile import default_profile

MARKER_SHIFT = 4  # markers drawn to sub-pixel precision 1/2**4 px


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
        native_hw = (h, w) if background is None else background.shape[:2]  # the camera's own pixels
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
        self._background_planes = np.ascontiguousarray(np.moveaxis(self.background, -1, 0))
        # the shading, and the position and sink planes of a profile of format 2: once per renderer
        self._light_planes = self.light.frame_planes(self.background, self.geometry.width_mm, self.geometry.height_mm)
        self._shade_scale = self._light_planes.scale  # (3, H, W) or None
        self._rng = np.random.default_rng(seed)
        # Sensor noise from a bank of precomputed fields, shifted at random per frame:
        # statistically the same per pixel, ~10x cheaper than fresh Gaussian draws.
        self._noise_planes: np.ndarray | None = None
        noise = self.spec.sensor_noise()
        self._noise = None if noise.silent else noise.bank(self._rng, 4, (h, w), native_hw)
        pitch = self.spec.marker_pitch_mm
        n_x = int(self.geometry.width_mm / pitch)
        n_y = int(self.geometry.height_mm / pitch)
        mx = (np.arange(n_x) - (n_x - 1) / 2) * pitch
        my = (np.arange(n_y) - (n_y - 1) / 2) * pitch
        self.marker_rest_mm = np.stack(np.meshgrid(mx, my), axis=-1).reshape(-1, 2)  # (x, y), +y up
        # The last inputs and what they gave: (uz, press planes), (centres in 1/16 px, shading).
        self._press_cache: tuple[np.ndarray, np.ndarray] | None = None
        self._marker_cache: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def _noise(self) -> np.ndarray | None:
        """The noise bank (4, H, W, 3) float32, or None for no noise (tests set it)."""
        return self._noise_bank

    @_noise.setter
    def _noise(self, bank: np.ndarray | None) -> None:
        self._noise_bank = bank
        self._noise_planes = None if bank is None else np.ascontiguousarray(np.moveaxis(bank, -1, 1))

    @classmethod
    def from_profile(cls, profile, kind: str = "rgb", seed: int = 0) -> "Renderer":
        """A renderer for ``kind`` with everything (frame, scale, noise, markers) from ``profile``."""
        return cls(profile.optics_spec(kind), profile.geometry(), seed=seed, profile=profile)

    def needs(self) -> frozenset[str]:
        """The displacement fields this sensor kind needs from the mechanics."""
        return frozenset({"uz", "uxy"}) if self.spec.has_markers else frozenset({"uz"})

    def _on_image(self, field: np.ndarray) -> np.ndarray:
        """A mechanics-grid field on the frame's pixels, by position: pixel column c is at
        x = (c - (W - 1) / 2) · mm_per_px, grid column i at (i - (nx - 1) / 2) · dx. Where the grid
        spans the frame exactly (square pads) that is ``cv2.resize``'s own mapping."""
        w, h = self.spec.width_px, self.spec.height_px
        field = field.astype(np.float32)
        ny, nx = field.shape
        dx = self.geometry.dx_mm
        if abs(nx * dx - self.geometry.width_mm) < 1e-9 and abs(ny * dx - self.geometry.height_mm) < 1e-9:
            return cv2.resize(field, (w, h), interpolation=cv2.INTER_CUBIC)
        step = self.mm_per_px / dx  # grid cells per pixel
        to_grid = np.array(
            [[step, 0.0, (nx - 1) / 2 - step * (w - 1) / 2], [0.0, step, (ny - 1) / 2 - step * (h - 1) / 2]]
        )
        return cv2.warpAffine(
            field, to_grid, (w, h), flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE
        )

    def sink_on_frame(self, uz_mm: np.ndarray) -> np.ndarray:
        """(H, W) float32 sink (mm, into the gel) of a mechanics-grid field on the frame's pixels."""
        return self._on_image(uz_mm)

    def slope_change(self, uz_mm: np.ndarray) -> np.ndarray:
        """(H, W, 3) colour change for the surface sink ``uz_mm`` (mechanics grid)."""
        return np.ascontiguousarray(np.moveaxis(self._change_planes(uz_mm), 0, -1))

    def _change_planes(self, uz_mm: np.ndarray) -> np.ndarray:
        """``slope_change`` as (3, H, W) planes."""
        z = self._on_image(uz_mm)
        sink = z.copy() if self.light.extended else None
        gx, gy = self.light.slopes(np.negative(z, out=z), self.mm_per_px)  # the sink as a height
        if self.spec.kind == "white_markers":
            gx2, gy2 = gx * gx, gy * gy
            den = np.add(1.0, gx2, out=gx)
            den += gy2
            gx2 += gy2
            tilt = np.sqrt(gx2, out=gx2)
            tilt /= np.sqrt(den, out=den)  # sin of the tilt, in [0, 1)
            tilt = -self.white_darkening * tilt
            return np.multiply(tilt, self._background_planes)
        return self.light.change_frame(gx, gy, sink, self._light_planes)

    def _press_planes(self, uz_mm: np.ndarray) -> np.ndarray:
        """(3, H, W) background plus the colour change for ``uz_mm``; the last one is kept."""
        cached = self._press_cache
        if cached is not None and np.array_equal(cached[0], uz_mm):
            return cached[1]
        planes = self._change_planes(uz_mm)
        planes += self._background_planes
        self._press_cache = (np.array(uz_mm, copy=True), planes)
        return planes

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
        """(H, W) float32 coverage of the markers at ``centres_px``, blurred."""
        return self._marker_mask_fixed(self._fixed_point(centres_px))

    def _fixed_point(self, centres_px: np.ndarray) -> np.ndarray:
        return np.rint(centres_px * (1 << MARKER_SHIFT)).astype(np.int64)  # round half to even, as round()

    def _marker_mask_fixed(self, centres_fixed: np.ndarray) -> np.ndarray:
        h, w = self.spec.height_px, self.spec.width_px
        mask = np.zeros((h, w), np.float32)
        radius = int(round(self.spec.marker_radius_mm / self.mm_per_px * (1 << MARKER_SHIFT)))
        for c, r in centres_fixed.tolist():
            cv2.circle(mask, (c, r), radius, 1.0, -1, cv2.LINE_AA, MARKER_SHIFT)
        return cv2.GaussianBlur(mask, (0, 0), 0.6)

    def _marker_shading(self, centres_px: np.ndarray) -> np.ndarray:
        """(H, W) factor the markers at ``centres_px`` multiply the frame by; the last is kept."""
        fixed = self._fixed_point(centres_px)
        cached = self._marker_cache
        if cached is not None and np.array_equal(cached[0], fixed):
            return cached[1]
        shading = 1.0 - self.spec.marker_darkness * self._marker_mask_fixed(fixed)
        self._marker_cache = (fixed, shading)
        return shading

    def render(self, fields: dict[str, np.ndarray]) -> np.ndarray:
        """BGR uint8 frame from the mechanics fields ("uz"; "ux", "uy" for markers)."""
        h, w = self.spec.height_px, self.spec.width_px
        uz = fields.get("uz")
        base = self._press_planes(uz) if uz is not None and np.any(uz) else self._background_planes
        img = np.empty((3, h, w), np.float32)
        src = base
        if self.spec.has_markers:
            centres = self.marker_positions_px(fields.get("ux"), fields.get("uy"))
            src = np.multiply(base, self._marker_shading(centres), out=img)
        if self._noise is not None and self._noise_planes is not None:
            k = int(self._rng.integers(len(self._noise)))
            dy, dx = (int(v) for v in self._rng.integers(0, (h, w)))
            noise = self._noise_planes[k]  # added shifted by (dy, dx), wrapping: np.roll's sum, without the copy
            for rows, noise_rows in ((slice(dy, h), slice(0, h - dy)), (slice(0, dy), slice(h - dy, h))):
                for cols, noise_cols in ((slice(dx, w), slice(0, w - dx)), (slice(0, dx), slice(w - dx, w))):
                    np.add(src[:, rows, cols], noise[:, noise_rows, noise_cols], out=img[:, rows, cols])
        elif src is not img:
            np.copyto(img, src)
        np.rint(soft_bound_inplace(img), out=img)
        frame = img.astype(np.uint8)
        return cv2.merge((frame[0], frame[1], frame[2]))
