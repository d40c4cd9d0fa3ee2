"""What the sensor's camera sees: the deformed gel rendered for three sensor kinds.

- ``rgb``: coloured lights from the sides; the colour change is looked up from the
  surface normal in a bounded table (``LightModel``), fitted to real presses by
  ``rig.sim.tactile.calibration.fit_optics`` and shipped in the sensor profile.
- ``rgb_markers``: the same with a printed marker grid.
- ``white_markers``: white light: a grey image darkened where the gel tilts, with markers.

Markers move with the tangential surface displacement of the gel. The profile's
background (the real GelSight Mini no-contact frame by default, or one you supply),
optical blur, vignetting for synthetic backgrounds and sensor noise complete the frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import map_coordinates

from rig.sim.tactile.contact import SensorGeometry

SENSOR_KINDS = ("rgb", "rgb_markers", "white_markers")
SHADINGS = ("multiplicative", "additive")
# A camera's response flattens near its ends; frames stay in [1, 254] so a deep press
# never shows clipped black or saturated colour. Values between the knees are untouched.
KNEE_LOW, KNEE_HIGH, FLOOR, CEIL = 16.0, 236.0, 1.0, 254.0


def soft_bound(img: np.ndarray) -> np.ndarray:
    """Compress values beyond the knees smoothly into [FLOOR, CEIL] (C¹, monotone)."""
    out = img.copy()
    hi = img > KNEE_HIGH
    out[hi] = KNEE_HIGH + (CEIL - KNEE_HIGH) * np.tanh((img[hi] - KNEE_HIGH) / (CEIL - KNEE_HIGH))
    lo = img < KNEE_LOW
    out[lo] = KNEE_LOW - (KNEE_LOW - FLOOR) * np.tanh((KNEE_LOW - img[lo]) / (KNEE_LOW - FLOOR))
    return out


def normal_lookup(gx: np.ndarray, gy: np.ndarray, bins: int) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear cells of the surface normal in a bins × bins table over (nx, ny) ∈ [-1, 1]².

    Returns flat table indices (..., 4) and weights (..., 4). The normal of any surface,
    however steep, lies in the table: the colour it looks up is one the fit produced.
    """
    inv = 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)
    u = (1.0 - gx * inv) * (0.5 * (bins - 1))  # nx = -gx / |(gx, gy, 1)|, image axes
    v = (1.0 - gy * inv) * (0.5 * (bins - 1))
    i0 = np.clip(np.floor(u).astype(np.int32), 0, bins - 2)
    j0 = np.clip(np.floor(v).astype(np.int32), 0, bins - 2)
    fu, fv = (u - i0).astype(np.float32), (v - j0).astype(np.float32)
    k = j0 * bins + i0
    idx = np.stack([k, k + 1, k + bins, k + bins + 1], axis=-1)
    w = np.stack([(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv], axis=-1)
    return idx, w


@dataclass(frozen=True)
class LightModel:
    """Colour change of the gel as a function of its surface normal and of position.

    ``table_bgr`` (3, N, N): per channel, the colour change (grey levels) for a surface
    normal (nx, ny) on an N × N grid over [-1, 1]² (rows: ny, columns: nx; image axes),
    interpolated bilinearly: a lookup table over surface gradient as in Taxim (Si &
    Yuan 2022), indexed by the normal so that every tilt has a bounded entry.
    ``shading``: "multiplicative" scales the change by the background's brightness at each
    pixel relative to ``reference_bgr`` (the light reaching each place differs, and the
    background shows how much); "additive" adds the same change everywhere.
    ``blur_mm``: optical blur of the surface slopes (gel scattering, camera focus).
    """

    table_bgr: np.ndarray
    blur_mm: float
    shading: str = "multiplicative"
    reference_bgr: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self):
        table = np.asarray(self.table_bgr, dtype=np.float32)
        if table.ndim != 3 or table.shape[0] != 3 or table.shape[1] != table.shape[2] or table.shape[1] < 3:
            raise ValueError(f"table_bgr must be 3 square tables of at least 3 × 3, got shape {table.shape}")
        if not np.all(np.isfinite(table)) or np.abs(table).max() > 255:
            raise ValueError("table_bgr entries must be finite colour changes within ±255 grey levels")
        object.__setattr__(self, "table_bgr", table)
        if self.shading not in SHADINGS:
            raise ValueError(f"shading must be one of {', '.join(SHADINGS)}, got {self.shading!r}")
        if not (np.isfinite(self.blur_mm) and 0 <= self.blur_mm <= 5):
            raise ValueError(f"blur_mm must be in [0, 5] mm, got {self.blur_mm}")
        ref = np.asarray(self.reference_bgr, dtype=float)
        if ref.shape != (3,) or not np.all(np.isfinite(ref)) or np.any(ref <= 0):
            raise ValueError(f"reference_bgr must be 3 finite numbers > 0, got {self.reference_bgr}")

    @property
    def bins(self) -> int:
        return self.table_bgr.shape[1]

    def slope_gain(self) -> float:
        """Mean colour change per unit slope at the flat gel (grey levels): small-tilt response."""
        t, c = self.table_bgr, self.bins // 2
        step = 2.0 / (self.bins - 1)
        dx = (t[:, c, c + 1] - t[:, c, c - 1]) / (2 * step)
        dy = (t[:, c + 1, c] - t[:, c - 1, c]) / (2 * step)
        return float(np.mean(np.hypot(dx, dy)))

    def slopes(self, z_mm: np.ndarray, mm_per_px: float) -> tuple[np.ndarray, np.ndarray]:
        """Blurred slopes (gx, gy) of the surface height ``z_mm`` (image axes)."""
        gy, gx = np.gradient(z_mm.astype(np.float32), np.float32(mm_per_px))
        blur_px = self.blur_mm / mm_per_px
        if blur_px > 0:
            gx = cv2.GaussianBlur(gx, (0, 0), blur_px)
            gy = cv2.GaussianBlur(gy, (0, 0), blur_px)
        return gx, gy

    def change(self, gx: np.ndarray, gy: np.ndarray, background: np.ndarray) -> np.ndarray:
        """(H, W, 3) colour change for slopes (gx, gy) over ``background`` (H, W, 3)."""
        idx, w = normal_lookup(gx, gy, self.bins)
        flat = self.table_bgr.reshape(3, -1)
        delta = np.stack([(flat[ch][idx] * w).sum(axis=-1) for ch in range(3)], axis=-1)
        if self.shading == "multiplicative":
            delta *= background / np.asarray(self.reference_bgr, dtype=np.float32)
        return delta


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
    """Renders mechanics fields into frames with a sensor profile's optics.

    ``light`` and ``background`` default to the profile's (the shipped GelSight Mini
    profile unless ``profile`` is given); ``background`` (any size, BGR) overrides it.
    """

    def __init__(self, spec: OpticsSpec | None = None, geometry: SensorGeometry | None = None,
                 background: np.ndarray | None = None, seed: int = 0, *, profile=None):
        from rig.sim.tactile.profile import default_profile

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
        self._noise = (self._rng.normal(0.0, self.spec.noise_std, (4, h, w, 3)).astype(np.float32)
                       if self.spec.noise_std > 0 else None)
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
        return cv2.resize(field.astype(np.float32), (self.spec.width_px, self.spec.height_px),
                          interpolation=cv2.INTER_CUBIC)

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
        return np.rint(soft_bound(img)).astype(np.uint8)
