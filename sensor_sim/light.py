"""The sensor's light model: colour change as a bounded function of the gel's surface normal.

Parameters only (what a sensor profile stores and the calibration fits); the renderer
that turns mechanics fields into frames with them is ``sensor_sim.optics``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import cv2
import numpy as np

from common.sensors import SENSOR_KINDS

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


def _corner_cells(gx: np.ndarray, gy: np.ndarray, bins: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """``normal_lookup`` unstacked: the first corner's flat index and the four weights, each
    shaped like ``gx``: the same numbers without building the (..., 4) arrays."""
    inv = 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)
    u = (1.0 - gx * inv) * (0.5 * (bins - 1))
    v = (1.0 - gy * inv) * (0.5 * (bins - 1))
    i0 = np.clip(np.floor(u).astype(np.int32), 0, bins - 2)
    j0 = np.clip(np.floor(v).astype(np.int32), 0, bins - 2)
    fu, fv = (u - i0).astype(np.float32), (v - j0).astype(np.float32)
    return j0 * bins + i0, [(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv]


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
        gx: np.ndarray
        gy: np.ndarray
        # z_mm is (H, W); numpy's stubs only type np.gradient's result as a pair for a 2-D array type
        z = cast("np.ndarray[tuple[int, int], np.dtype[np.float32]]", z_mm.astype(np.float32))
        gy, gx = np.gradient(z, np.float32(mm_per_px))
        blur_px = self.blur_mm / mm_per_px
        if blur_px > 0:
            gx = cv2.GaussianBlur(gx, (0, 0), blur_px)
            gy = cv2.GaussianBlur(gy, (0, 0), blur_px)
        return gx, gy

    def change(self, gx: np.ndarray, gy: np.ndarray, background: np.ndarray) -> np.ndarray:
        """(H, W, 3) colour change for slopes (gx, gy) over ``background`` (H, W, 3)."""
        # Per channel, one contiguous gather per corner, the corners summed in the order a
        # (..., 4) sum takes them: the same float32 bits as stacking the corners and summing
        # (tested), ~5x faster (most of a simulated frame's render).
        k, w = _corner_cells(gx, gy, self.bins)
        corners = [k, k + 1, k + self.bins, k + self.bins + 1]
        channels = []
        for table in self.table_bgr.reshape(3, -1):
            acc = np.take(table, corners[0])
            acc *= w[0]
            for index, weight in zip(corners[1:], w[1:]):
                corner = np.take(table, index)
                corner *= weight
                acc += corner
            channels.append(acc)
        delta = np.stack(channels, axis=-1)
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
