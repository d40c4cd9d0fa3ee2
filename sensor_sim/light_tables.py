"""Where a surface normal falls in the light model's lookup tables (sensor_sim/light.py): the
slopes of a height map (``gradient``), the normal's place in a bins × bins table over (nx, ny)
(``table_coordinates``) and its bilinear cells and weights, stacked (``normal_lookup``, which the
calibration fits through) or unstacked (``corner_cells``, the renderer's gather). The same
operations in the same order in each, so that every path gives the same numbers.
"""

from __future__ import annotations

import numpy as np


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


def table_coordinates(gx: np.ndarray, gy: np.ndarray, bins: int) -> tuple[np.ndarray, np.ndarray]:
    """(u, v): where the surface normal of slopes (gx, gy) falls in the table, in cells
    (columns, rows), as ``normal_lookup`` computes them (the same operations in the same order)."""
    s = gx * gx
    s += 1.0
    s += gy * gy  # 1 + gx² + gy², summed left to right as written in normal_lookup
    np.sqrt(s, out=s)
    inv = np.divide(1.0, s, out=s)
    half = 0.5 * (bins - 1)
    u = gx * inv
    np.subtract(1.0, u, out=u)
    u *= half
    v = np.multiply(gy, inv, out=inv)
    np.subtract(1.0, v, out=v)
    v *= half
    return u, v


def corner_cells(gx: np.ndarray, gy: np.ndarray, bins: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """``normal_lookup`` unstacked: the first corner's flat index and the four weights, each
    shaped like ``gx``: the same numbers without building the (..., 4) arrays.

    The same operations in the same order, in place where a temporary is not needed. For
    float32 slopes the fraction ``u - i0`` is taken in float32: exact (Sterbenz: i0 <= u <= 2 i0
    for i0 >= 1, and u - 0 = u), so it equals the float64 difference rounded to float32."""
    u, v = table_coordinates(gx, gy, bins)
    # floor, then clipped to the table: u > -1 always (|gx| / |(gx, gy, 1)| <= 1 to a few ulps),
    # so truncation toward zero, clipped, is the same cell (NaN: both casts give INT_MIN, clipped to 0)
    i0 = u.astype(np.int32)
    np.minimum(np.maximum(i0, 0, out=i0), bins - 2, out=i0)
    j0 = v.astype(np.int32)
    np.minimum(np.maximum(j0, 0, out=j0), bins - 2, out=j0)
    u -= i0.astype(u.dtype)
    v -= j0.astype(v.dtype)
    fu, fv = u.astype(np.float32, copy=False), v.astype(np.float32, copy=False)
    a, b = 1 - fu, 1 - fv
    k = j0 * bins
    k += i0
    return k, [a * b, fu * b, a * fv, np.multiply(fu, fv, out=fu)]


def gradient(z: np.ndarray, step: np.float32) -> tuple[np.ndarray, np.ndarray]:
    """``np.gradient(z, step)`` of a 2-D float32 array, (d/drow, d/dcol): the same operations
    (central differences over ``2. * step`` inside, one-sided over ``step`` at the edges)
    written straight into the results, without np.gradient's general-case bookkeeping."""
    if z.ndim != 2 or min(z.shape) < 2:
        gy, gx = np.gradient(z, step)
        return gy, gx
    two_step = 2.0 * step
    gy, gx = np.empty_like(z), np.empty_like(z)
    np.divide(np.subtract(z[2:], z[:-2], out=gy[1:-1]), two_step, out=gy[1:-1])
    np.divide(np.subtract(z[1], z[0], out=gy[0]), step, out=gy[0])
    np.divide(np.subtract(z[-1], z[-2], out=gy[-1]), step, out=gy[-1])
    np.divide(np.subtract(z[:, 2:], z[:, :-2], out=gx[:, 1:-1]), two_step, out=gx[:, 1:-1])
    np.divide(np.subtract(z[:, 1], z[:, 0], out=gx[:, 0]), step, out=gx[:, 0])
    np.divide(np.subtract(z[:, -1], z[:, -2], out=gx[:, -1]), step, out=gx[:, -1])
    return gy, gx
