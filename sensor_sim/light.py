"""The sensor's light model: colour change as a bounded function of the gel's surface normal,
of where on the gel it is, and of how far the gel is pressed in.

Per channel, at a place (x, y) of the frame with surface normal n and sink s (mm):

    change = shade(x, y) · [T(n) + x̃·Tx(n) + ỹ·Ty(n) + s·(k + kx·x̃ + ky·ỹ)]
             (+ s·(kxx·x̃² + kxy·x̃ỹ + kyy·ỹ²) + s²·(q + qx·x̃ + qy·ỹ + qxx·x̃² + qxy·x̃ỹ + qyy·ỹ²): the
             quadratic sink field, ``sink_bgr`` of SINK_FIELD_TERMS columns, profiles of format 4)
             (+ shade(x, y) · s · U(n): the sink table, ``sink_table_bgr``, profiles of format 5)

T, Tx, Ty: smooth lookup tables over the normal (T(flat) = 0); x̃, ỹ: the position from the
frame's centre over ``position_scale_mm`` (image axes, bounded over the frame); s: the sink, held
at ``sink_max_mm`` beyond it (the deepest the fitted presses were); shade: the
background's brightness relative to ``reference_bgr`` (multiplicative shading). Without the
position and sink terms (``position_bgr``, ``sink_bgr`` None: profiles of format 1) it is the
table alone, computed as before. Parameters only (what a sensor profile stores and the
calibration fits); the renderer that turns mechanics fields into frames is ``sensor_sim.optics``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from common.sensors import SENSOR_KINDS
from sensor_sim.light_tables import corner_cells, gradient, table_coordinates
from sensor_sim.noise import SensorNoise

SHADINGS = ("multiplicative", "additive")
# A camera's response flattens near its ends; frames stay in [1, 254] so a deep press
# never shows clipped black or saturated colour. Values between the knees are untouched.
KNEE_LOW, KNEE_HIGH, FLOOR, CEIL = 16.0, 236.0, 1.0, 254.0
# The sink's terms per channel: 3 (k, kx, ky: linear in the sink and the position) or SINK_FIELD_TERMS
# (per mm of sink 1, x̃, ỹ, x̃², x̃ỹ, ỹ², then the same per mm² of sink: the centre's colour across the field, issue 40).
SINK_LINEAR_TERMS, SINK_FIELD_TERMS = 3, 12


def soft_bound(img: np.ndarray) -> np.ndarray:
    """Compress values beyond the knees smoothly into [FLOOR, CEIL] (C¹, monotone)."""
    return soft_bound_inplace(img.copy())


def soft_bound_inplace(img: np.ndarray) -> np.ndarray:
    """``soft_bound`` on ``img`` itself (returned): the same numbers, no copy, and no
    indexing at all when nothing lies beyond the knees (most frames)."""
    hi = img > KNEE_HIGH
    if hi.any():
        img[hi] = KNEE_HIGH + (CEIL - KNEE_HIGH) * np.tanh((img[hi] - KNEE_HIGH) / (CEIL - KNEE_HIGH))
    lo = img < KNEE_LOW  # values raised above KNEE_HIGH stay above it: the same cells as before
    if lo.any():
        img[lo] = KNEE_LOW - (KNEE_LOW - FLOOR) * np.tanh((KNEE_LOW - img[lo]) / (KNEE_LOW - FLOOR))
    return img


REMAP_MAX_SIDE = 32767  # cv2.remap's limit on a map's sides (SHRT_MAX)


@functools.cache
def remap_interpolates_exactly() -> bool:
    """True when this OpenCV's bilinear ``cv2.remap`` of a float32 table at float32 coordinates
    is the plain bilinear formula to float32 rounding (OpenCV 5 measured: 2e-5 grey levels on
    a ±100 table). OpenCV 4 rounds the fraction to 1/32 of a cell (errors of grey levels):
    then the colour lookup keeps its own gather."""
    rng = np.random.default_rng(0)
    bins = 21
    table = rng.uniform(-100.0, 100.0, (bins, bins)).astype(np.float32)
    u = rng.uniform(0.0, bins - 1, (64, 64)).astype(np.float32)
    v = rng.uniform(0.0, bins - 1, (64, 64)).astype(np.float32)
    got = cv2.remap(table, u, v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    i0 = np.minimum(u.astype(np.int64), bins - 2)
    j0 = np.minimum(v.astype(np.int64), bins - 2)
    fu, fv = u - i0, v - j0
    t = table.astype(np.float64)
    want = (t[j0, i0] * (1 - fu) + t[j0, i0 + 1] * fu) * (1 - fv) + (
        t[j0 + 1, i0] * (1 - fu) + t[j0 + 1, i0 + 1] * fu
    ) * fv
    return got.shape == want.shape and float(np.abs(got - want).max()) < 1e-3


@dataclass
class FramePlanes:
    """A renderer's constants for ``LightModel.change_frame`` (each (3, H, W) float32 or None):
    the shading, the shading times x̃ and ỹ, the position tables per channel, and the sink's
    change per mm (shading included)."""

    scale: np.ndarray | None  # None: additive shading
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    position: list[list[np.ndarray]] | None = None
    sink: np.ndarray | None = None
    sink2: np.ndarray | None = None  # the change per mm² of sink (the quadratic sink field), shading included
    sink_table: list[np.ndarray] | None = None  # each channel's sink table U (per mm of sink; format 5)


def _lookup_planes(tables: list[np.ndarray], gx: np.ndarray, gy: np.ndarray, bins: int, exact: bool) -> np.ndarray:
    """(len(tables), H, W): each (bins, bins) table looked up bilinearly at the normal of (gx, gy)."""
    if not exact and gx.ndim == 2 and max(gx.shape) < REMAP_MAX_SIDE and remap_interpolates_exactly():
        u, v = table_coordinates(gx, gy, bins)
        u, v = u.astype(np.float32, copy=False), v.astype(np.float32, copy=False)
        return np.stack([cv2.remap(t, u, v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE) for t in tables]).astype(
            np.float32, copy=False
        )
    k, w = corner_cells(gx, gy, bins)
    out = np.empty((len(tables), *k.shape), np.float32)
    for i, table in enumerate(tables):
        flat = table.ravel()
        acc = np.multiply(flat.take(k), w[0], out=out[i])
        for j, offset in enumerate((1, bins, bins + 1), start=1):
            acc += flat.take(k + offset) * w[j]
    return out


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
    ``position_bgr`` (3, 2, N, N): per channel, the tables Tx and Ty (change per unit of x̃, ỹ);
    ``sink_bgr`` (3, 3): per channel, the change per mm of sink: k, kx, ky; or (3, SINK_FIELD_TERMS): the
    quadratic sink field (per mm of sink 1, x̃, ỹ, x̃², x̃ỹ, ỹ², then per mm² the same six);
    ``position_scale_mm``: the length that makes x̃, ỹ (> 0 when either is given);
    ``position_range``: (x̃ low, x̃ high, ỹ low, ỹ high) where the presses fitted them were: beyond
    it the position terms stay at its edge (a light fitted in one region is not extrapolated);
    ``sink_max_mm``: the deepest sink of those presses: deeper, the sink terms stay at its value
    (a linear change fitted on shallow presses is not carried to deep ones; inf: not held);
    ``sink_table_bgr`` (3, N, N): per channel, the change per mm of sink at each normal, U(n) (U(flat) = 0:
    there the sink terms say it), shaded like T: the pressed-in gel's response to a tilt differs from the
    unpressed gel's at the same normal (the contact's centre against the gel around it; issue 40).
    """

    table_bgr: np.ndarray
    blur_mm: float
    shading: str = "multiplicative"
    reference_bgr: tuple[float, float, float] = (1.0, 1.0, 1.0)
    position_bgr: np.ndarray | None = None
    sink_bgr: np.ndarray | None = None
    position_scale_mm: float = 0.0
    position_range: tuple[float, float, float, float] = (-math.inf, math.inf, -math.inf, math.inf)
    sink_max_mm: float = math.inf
    sink_table_bgr: np.ndarray | None = None
    _cells: np.ndarray = field(init=False, repr=False, compare=False)  # derived from table_bgr
    _planes: list[np.ndarray] = field(init=False, repr=False, compare=False)  # each channel's table

    def __post_init__(self):
        table = np.asarray(self.table_bgr, dtype=np.float32)
        if table.ndim != 3 or table.shape[0] != 3 or table.shape[1] != table.shape[2] or table.shape[1] < 3:
            raise ValueError(f"table_bgr must be 3 square tables of at least 3 × 3, got shape {table.shape}")
        if not np.all(np.isfinite(table)) or np.abs(table).max() > 255:
            raise ValueError("table_bgr entries must be finite colour changes within ±255 grey levels")
        object.__setattr__(self, "table_bgr", table)
        self._check_position_and_sink(table.shape[1])
        # Per channel and corner, each cell's corner value: row 4 * channel + corner (corners
        # at flat offsets 0, 1, bins, bins + 1), so one gather fetches all twelve.
        bins, flat = table.shape[1], table.reshape(3, -1)
        cells = np.zeros((12, bins * bins), np.float32)
        for corner, offset in enumerate((0, 1, bins, bins + 1)):
            cells[corner::4, : bins * bins - offset] = flat[:, offset:]
        object.__setattr__(self, "_cells", cells)
        object.__setattr__(self, "_planes", [np.ascontiguousarray(plane) for plane in table])
        if self.shading not in SHADINGS:
            raise ValueError(f"shading must be one of {', '.join(SHADINGS)}, got {self.shading!r}")
        if not (np.isfinite(self.blur_mm) and 0 <= self.blur_mm <= 5):
            raise ValueError(f"blur_mm must be in [0, 5] mm, got {self.blur_mm}")
        ref = np.asarray(self.reference_bgr, dtype=float)
        if ref.shape != (3,) or not np.all(np.isfinite(ref)) or np.any(ref <= 0):
            raise ValueError(f"reference_bgr must be 3 finite numbers > 0, got {self.reference_bgr}")

    def _check_position_and_sink(self, bins: int) -> None:
        if self.position_bgr is not None:
            pos = np.asarray(self.position_bgr, dtype=np.float32)
            if pos.shape != (3, 2, bins, bins):
                raise ValueError(f"position_bgr must be (3, 2, {bins}, {bins}) tables, got shape {pos.shape}")
            if not np.all(np.isfinite(pos)) or np.abs(pos).max() > 255:
                raise ValueError("position_bgr entries must be finite colour changes within ±255 grey levels")
            object.__setattr__(self, "position_bgr", pos)
        if self.sink_bgr is not None:
            sink = np.asarray(self.sink_bgr, dtype=np.float32)
            ok = sink.ndim == 2 and sink.shape[0] == 3 and sink.shape[1] in (SINK_LINEAR_TERMS, SINK_FIELD_TERMS)
            if not ok or not np.all(np.isfinite(sink)) or np.abs(sink).max() > 1000:
                raise ValueError(
                    f"sink_bgr must be 3 × {SINK_LINEAR_TERMS} (or 3 × {SINK_FIELD_TERMS}) finite changes per mm of "
                    "sink within ±1000 grey levels"
                )
            object.__setattr__(self, "sink_bgr", sink)
        if self.sink_table_bgr is not None:
            table = np.asarray(self.sink_table_bgr, dtype=np.float32)
            if table.shape != (3, bins, bins) or not np.all(np.isfinite(table)) or np.abs(table).max() > 1000:
                raise ValueError(
                    f"sink_table_bgr must be (3, {bins}, {bins}) finite changes per mm of sink within ±1000 grey "
                    f"levels, got shape {table.shape}"
                )
            object.__setattr__(self, "sink_table_bgr", table)
        positional = self.position_bgr is not None or (self.sink_bgr is not None and np.any(self.sink_bgr[:, 1:]))
        scale = self.position_scale_mm
        if positional and not (np.isfinite(scale) and 0 < scale <= 1000):
            raise ValueError(f"position_scale_mm must be in (0, 1000] mm with position terms, got {scale}")
        lo_x, hi_x, lo_y, hi_y = (float(v) for v in self.position_range)
        if any(math.isnan(v) for v in (lo_x, hi_x, lo_y, hi_y)) or lo_x > hi_x or lo_y > hi_y:
            raise ValueError(f"position_range must be x low <= x high, y low <= y high, got {self.position_range}")
        if not (self.sink_max_mm > 0):  # NaN fails too
            raise ValueError(f"sink_max_mm must be > 0 mm (inf: not held), got {self.sink_max_mm}")

    @property
    def bins(self) -> int:
        return self.table_bgr.shape[1]

    @property
    def extended(self) -> bool:
        """Position or sink terms beside the table (a format 2 profile's light)."""
        return self.position_bgr is not None or self.sink_bgr is not None or self.sink_table_bgr is not None

    @property
    def profile_format(self) -> int:
        """The profile format a fitted light is written in: 5 with the sink table, 4 with the quadratic sink
        field, else 3."""
        return 5 if self.sink_table_bgr is not None else 4 if self.quadratic_sink else 3

    def frame_planes(self, background: np.ndarray, width_mm: float, height_mm: float) -> "FramePlanes":
        """What ``change_frame`` multiplies for a frame over ``background`` (H, W, 3) spanning
        ``width_mm`` × ``height_mm`` centred on the sensor: made once per renderer."""
        h, w = background.shape[:2]
        planes = FramePlanes(self.shade_scale(background))
        if not self.extended:
            return planes
        scale = planes.scale if planes.scale is not None else np.ones((3, h, w), np.float32)
        s = self.position_scale_mm or 1.0
        xs = ((np.arange(w, dtype=np.float64) + 0.5) / w - 0.5) * (width_mm / s)
        ys = ((np.arange(h, dtype=np.float64) + 0.5) / h - 0.5) * (height_mm / s)
        lo_x, hi_x, lo_y, hi_y = self.position_range
        x_tilde = np.broadcast_to(np.clip(xs, lo_x, hi_x)[None, :], (h, w)).astype(np.float32)
        y_tilde = np.broadcast_to(np.clip(ys, lo_y, hi_y)[:, None], (h, w)).astype(np.float32)
        if self.position_bgr is not None:
            planes.x = np.ascontiguousarray(scale * x_tilde)
            planes.y = np.ascontiguousarray(scale * y_tilde)
            planes.position = [[np.ascontiguousarray(self.position_bgr[ch, k]) for k in range(2)] for ch in range(3)]
        if self.sink_bgr is not None:
            k = self.sink_bgr
            per_mm = k[:, 0, None, None] + k[:, 1, None, None] * x_tilde + k[:, 2, None, None] * y_tilde
            if self.quadratic_sink:
                basis = (x_tilde * x_tilde, x_tilde * y_tilde, y_tilde * y_tilde)
                per_mm = per_mm + sum(k[:, 3 + j, None, None] * b for j, b in enumerate(basis))
                per_mm2 = k[:, 6, None, None] + k[:, 7, None, None] * x_tilde + k[:, 8, None, None] * y_tilde
                per_mm2 = per_mm2 + sum(k[:, 9 + j, None, None] * b for j, b in enumerate(basis))
                planes.sink2 = np.ascontiguousarray((scale * per_mm2).astype(np.float32))
            planes.sink = np.ascontiguousarray((scale * per_mm).astype(np.float32))
        if self.sink_table_bgr is not None:
            planes.sink_table = [np.ascontiguousarray(t) for t in self.sink_table_bgr]
        return planes

    @property
    def quadratic_sink(self) -> bool:
        """The sink's terms are the quadratic sink field (SINK_FIELD_TERMS per channel; format 4)."""
        return self.sink_bgr is not None and self.sink_bgr.shape[1] == SINK_FIELD_TERMS

    def change_frame(
        self, gx: np.ndarray, gy: np.ndarray, sink_mm: np.ndarray | None, planes: "FramePlanes", *, exact=False
    ) -> np.ndarray:
        """(3, H, W) colour change of a frame: slopes (gx, gy), the sink (mm, into the gel) and the
        frame's ``planes``. Without position and sink terms: ``change_planar`` itself (the same bits)."""
        out = self.change_planar(gx, gy, planes.scale, exact=exact)
        if not self.extended:
            return out
        if planes.position is not None:
            for k, weight in enumerate((planes.x, planes.y)):
                tables = [planes.position[ch][k] for ch in range(3)]
                looked = _lookup_planes(tables, gx, gy, self.bins, exact)
                looked *= weight
                out += looked
        if (planes.sink is not None or planes.sink_table is not None) and sink_mm is not None:
            sink = sink_mm.astype(np.float32, copy=False)
            if math.isfinite(self.sink_max_mm):
                sink = np.minimum(sink, np.float32(self.sink_max_mm))
            if planes.sink is not None:
                out += planes.sink * sink
            if planes.sink2 is not None:
                out += planes.sink2 * (sink * sink)
            if planes.sink_table is not None:
                looked = _lookup_planes(planes.sink_table, gx, gy, self.bins, exact)
                if planes.scale is not None:
                    looked *= planes.scale
                looked *= sink
                out += looked
        np.clip(out, -255.0, 255.0, out=out)
        return out

    def slope_gain(self) -> float:
        """Mean colour change per unit slope at the flat gel (grey levels): small-tilt response."""
        t, c = self.table_bgr, self.bins // 2
        step = 2.0 / (self.bins - 1)
        dx = (t[:, c, c + 1] - t[:, c, c - 1]) / (2 * step)
        dy = (t[:, c + 1, c] - t[:, c - 1, c]) / (2 * step)
        return float(np.mean(np.hypot(dx, dy)))

    def slopes(self, z_mm: np.ndarray, mm_per_px: float) -> tuple[np.ndarray, np.ndarray]:
        """Blurred slopes (gx, gy) of the surface height ``z_mm`` (image axes)."""
        gy, gx = gradient(z_mm.astype(np.float32, copy=False), np.float32(mm_per_px))
        blur_px = self.blur_mm / mm_per_px
        if blur_px > 0:
            gx = cv2.GaussianBlur(gx, (0, 0), blur_px)
            gy = cv2.GaussianBlur(gy, (0, 0), blur_px)
        return gx, gy

    def change(self, gx: np.ndarray, gy: np.ndarray, background: np.ndarray) -> np.ndarray:
        """(H, W, 3) colour change for slopes (gx, gy) over ``background`` (H, W, 3)."""
        return np.ascontiguousarray(np.moveaxis(self.change_planar(gx, gy, self.shade_scale(background)), 0, -1))

    def shade_scale(self, background: np.ndarray) -> np.ndarray | None:
        """(3, H, W) factor ``change_planar`` applies for ``background`` (H, W, 3); None when
        additive. Constant per background: a renderer computes it once."""
        if self.shading != "multiplicative":
            return None
        return np.ascontiguousarray(np.moveaxis(background / np.asarray(self.reference_bgr, dtype=np.float32), -1, 0))

    def change_planar(
        self, gx: np.ndarray, gy: np.ndarray, scale: np.ndarray | None = None, *, exact: bool = False
    ) -> np.ndarray:
        """``change`` as (3, H, W) planes, times ``scale`` (``shade_scale``) when given.

        Per channel, the four corners weighted and summed in the order a (..., 4) sum takes
        them: the same float32 bits as stacking the corners and summing (tested). One gather
        fetches every channel's corners; each plane is contiguous.

        Where ``cv2.remap`` interpolates exactly (``remap_interpolates_exactly``) it does the
        lookup, three times faster: the same bilinear formula, to float32 rounding (the
        frames' grey levels differ from the gather's in a few pixels in a million, by 1;
        ``exact=True`` keeps the gather)."""
        if not exact and gx.ndim == 2 and max(gx.shape) < REMAP_MAX_SIDE and remap_interpolates_exactly():
            u, v = table_coordinates(gx, gy, self.bins)
            u, v = u.astype(np.float32, copy=False), v.astype(np.float32, copy=False)
            planes = np.empty((3, *u.shape), np.float32)
            for ch in range(3):
                got = cv2.remap(
                    self._planes[ch], u, v, cv2.INTER_LINEAR, dst=planes[ch], borderMode=cv2.BORDER_REPLICATE
                )
                if got.ctypes.data != planes[ch].ctypes.data:  # OpenCV chose a buffer of its own
                    planes[ch] = got
                if scale is not None:
                    planes[ch] *= scale[ch]
            return planes
        k, w = corner_cells(gx, gy, self.bins)
        corners = self._cells.take(k, axis=1)
        out = np.empty((3, *k.shape), np.float32)
        for ch in range(3):
            acc = np.multiply(corners[4 * ch], w[0], out=out[ch])
            for j in range(1, 4):
                corner = corners[4 * ch + j]
                corner *= w[j]
                acc += corner
            if scale is not None:
                acc *= scale[ch]
        return out


@dataclass(frozen=True)
class OpticsSpec:
    kind: str = "rgb"
    height_px: int = 256
    width_px: int = 256
    noise_std: float = 1.0  # grey levels, per pixel and channel, independent (format-1 profiles)
    noise: SensorNoise | None = None  # the camera's noise as a profile of format 2 measures it (overrides noise_std)
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

    def sensor_noise(self) -> SensorNoise:
        """The noise frames get: ``noise``, else independent ``noise_std`` at the frame's pixels."""
        if self.noise is not None:
            return self.noise
        return SensorNoise((self.noise_std,) * 3, native=False)
