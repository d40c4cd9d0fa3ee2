"""The paper's indenters as height maps, and the image of each one's contact face.

Besides the paper's objects: ``plate20mm``, a rigid plate covering the whole pad, the
stiffest contact the simulated rig can press (for the force guard's worst case).

``Indenter.separation(u, v)`` is the height (mm, ≥ 0) of the face above its lowest
point at local coordinates (u, v) mm, where the face is not there it is FAR_MM.
``feature_mm`` is the face's smallest feature (a sphere's diameter, a ring's width, a
texture's half period): a contact solver needs about two cells across it to see it.
``texture_mm`` is a texture board's band of texture periods (shortest, longest), where the
texture-fidelity measure looks (model/evaluation/texture_measure.py); None for a shape.
``object_image`` is what a camera looking at the contact face sees: the condition
image of the learned model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, ClassVar

import numpy as np

FAR_MM = 50.0  # "no material here": far beyond any indentation


@dataclass(frozen=True)
class Indenter:
    name: str
    description: str
    radius_mm: float  # bounding radius of the face (for cropping and placement)
    separation: Callable[[np.ndarray, np.ndarray], np.ndarray] = field(repr=False)
    color_bgr: tuple[int, int, int] = (170, 170, 175)  # steel / 3D-print grey
    feature_mm: float | None = None  # smallest feature of the face; None: its whole width (2 × radius_mm)
    texture_mm: tuple[float, float] | None = None  # a board's texture periods, shortest and longest
    has_geometry: ClassVar[bool] = True  # an object file without a height map has none (objects/object_file.py)

    @property
    def smallest_feature_mm(self) -> float:
        return self.feature_mm if self.feature_mm is not None else 2.0 * self.radius_mm

    def separation_at(self, X: np.ndarray, Y: np.ndarray, x_mm: float, y_mm: float, theta_deg: float) -> np.ndarray:
        """Separation on sensor coordinates (X, Y) mm for the indenter axis at (x, y), turned by θ."""
        c, s = math.cos(math.radians(theta_deg)), math.sin(math.radians(theta_deg))
        dx, dy = X - x_mm, Y - y_mm
        return self.separation(c * dx + s * dy, -s * dx + c * dy)

    def object_image(self, size_px: int = 256, mm_per_px: float = 0.0625) -> np.ndarray:
        """BGR uint8 image of the contact face, centred, as a camera facing it sees it.

        Material is shaded by depth (the contact face brightest, receding parts darker);
        where there is no material the background is black.
        """
        half = (size_px - 1) / 2
        coords = (np.arange(size_px) - half) * mm_per_px
        U, V = np.meshgrid(coords, -coords)  # image rows go down, v goes up
        h = self.separation(U, V)
        present = h < FAR_MM
        relief = min(3.0, 2.0 * float(h[present].max())) if present.any() else 3.0
        depth_shade = np.clip(1.0 - h / max(relief, 1e-6), 0.25, 1.0)
        img = np.zeros((size_px, size_px, 3), np.float64)
        for ch, value in enumerate(self.color_bgr):
            img[..., ch] = np.where(present, value * depth_shade, 0.0)
        return np.clip(img, 0, 255).astype(np.uint8)


def _radius(u, v):
    return np.hypot(u, v)


def sphere(diameter_mm: float) -> Indenter:
    r_ball = diameter_mm / 2

    def sep(u, v):
        r2 = u * u + v * v
        return np.where(r2 < r_ball * r_ball, r_ball - np.sqrt(np.maximum(r_ball * r_ball - r2, 0.0)), FAR_MM)

    return Indenter(
        f"sphere{diameter_mm:g}mm", f"sphere, {diameter_mm:g} mm diameter", r_ball, sep, feature_mm=diameter_mm
    )


def flat_circle(diameter_mm: float) -> Indenter:
    a = diameter_mm / 2
    return Indenter(
        f"circle{diameter_mm:g}mm",
        f"flat circular punch, {diameter_mm:g} mm diameter",
        a,
        lambda u, v: np.where(_radius(u, v) <= a, 0.0, FAR_MM),
        feature_mm=diameter_mm,
    )


def _flat_square(name: str, description: str, side_mm: float) -> Indenter:
    s = side_mm / 2
    return Indenter(
        name,
        description,
        s * math.sqrt(2),
        lambda u, v: np.where((np.abs(u) <= s) & (np.abs(v) <= s), 0.0, FAR_MM),
        feature_mm=side_mm,
    )


def square(side_mm: float = 6.0) -> Indenter:
    return _flat_square("square", f"flat square punch, {side_mm:g} mm side", side_mm)


def plate(side_mm: float = 20.0) -> Indenter:
    """A rigid flat plate larger than the pad (14-16 mm): the stiffest contact there is,
    the whole gel pressed at once (docs/simulator.md, "Stopping": its stiffness table)."""
    return _flat_square(f"plate{side_mm:g}mm", f"rigid flat plate, {side_mm:g} mm square, covers the pad", side_mm)


def ring(outer_mm: float = 8.0, inner_mm: float = 5.0) -> Indenter:
    ro, ri = outer_mm / 2, inner_mm / 2

    def sep(u, v):
        r = _radius(u, v)
        return np.where((r <= ro) & (r >= ri), 0.0, FAR_MM)

    return Indenter("ring", f"flat ring, {outer_mm:g}/{inner_mm:g} mm diameters", ro, sep, feature_mm=ro - ri)


def heart(width_mm: float = 8.0) -> Indenter:
    scale = width_mm / 2.6  # the implicit curve spans about 2.6 units across

    def sep(u, v):
        x, y = u / scale, v / scale + 0.15
        inside = (x * x + y * y - 1) ** 3 - x * x * y**3 <= 0
        return np.where(inside, 0.0, FAR_MM)

    return Indenter("heart", f"flat heart, {width_mm:g} mm wide", width_mm * 0.7, sep, feature_mm=width_mm / 2)


def woven(period_mm: float = 2.0, amplitude_mm: float = 0.25) -> Indenter:
    """A woven board: over/under threads, a flat board larger than any sensor."""
    k = 2 * math.pi / period_mm

    def sep(u, v):
        warp = np.abs(np.sin(k * u / 2)) * (np.sign(np.sin(k * v / 2)) > 0)
        weft = np.abs(np.sin(k * v / 2)) * (np.sign(np.sin(k * u / 2)) <= 0)
        top = np.maximum(warp, weft)
        return amplitude_mm * (1.0 - top)

    # threads every period (|sin| repeats each period_mm), over and under every two periods
    return Indenter(
        "woven",
        f"woven texture board, {period_mm:g} mm period",
        100.0,
        sep,
        (90, 140, 200),
        feature_mm=period_mm / 2,
        texture_mm=(period_mm / 2, 2 * period_mm),
    )


def ridged(period_mm: float = 1.5, amplitude_mm: float = 0.2) -> Indenter:
    """A ridged board: straight parallel ridges across y, a smooth (1 − cos) profile, a board
    larger than any sensor — a texture neither woven nor irregular, for holding a board out."""
    k = 2 * math.pi / period_mm

    def sep(u, v):
        u, v = np.broadcast_arrays(u, v)
        return amplitude_mm * 0.5 * (1.0 + np.cos(k * u))

    return Indenter(
        "ridged",
        f"ridged texture board, {period_mm:g} mm period",
        100.0,
        sep,
        (150, 120, 90),
        feature_mm=period_mm / 2,
        texture_mm=(period_mm / 2, 2 * period_mm),
    )


def irregular(seed: int = 7, amplitude_mm: float = 0.3, corr_mm: float = 0.8) -> Indenter:
    """An irregular texture: smooth random bumps (fixed seed), a board larger than any sensor.

    Rastered once at 0.05 mm and interpolated, so a solve costs a lookup, not 400 bumps.
    """
    from scipy.ndimage import map_coordinates

    rng = np.random.default_rng(seed)
    centres = rng.uniform(-14, 14, size=(500, 2))
    heights = rng.uniform(0.3, 1.0, size=500)
    step, half = 0.05, 15.0
    axis = np.arange(-half, half + step / 2, step)
    U, V = np.meshgrid(axis, axis)
    top = np.zeros_like(U)
    for (cx, cy), hgt in zip(centres, heights):
        near = np.abs(U[0] - cx) < 4 * corr_mm
        cols = np.nonzero(near)[0]
        rows = np.nonzero(np.abs(V[:, 0] - cy) < 4 * corr_mm)[0]
        if cols.size and rows.size:
            sub = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
            top[sub] = np.maximum(top[sub], hgt * np.exp(-((U[sub] - cx) ** 2 + (V[sub] - cy) ** 2) / (2 * corr_mm**2)))
    raster = amplitude_mm * (1.0 - top)

    def sep(u, v):
        u, v = np.broadcast_arrays(u, v)
        coords = np.stack([(v + half) / step, (u + half) / step])
        return map_coordinates(raster, coords.reshape(2, -1), order=1, mode="nearest").reshape(u.shape)

    # bumps of width ~2σ spaced ~1.3 mm apart (500 over 28 × 28 mm), clustering up to a few mm
    return Indenter(
        "irregular",
        "irregular bumpy texture board",
        100.0,
        sep,
        (120, 160, 120),
        feature_mm=corr_mm,
        texture_mm=(corr_mm, 5 * corr_mm),
    )


INDENTERS: dict[str, Callable[[], Indenter]] = {
    "sphere4mm": lambda: sphere(4.0),
    "sphere10mm": lambda: sphere(10.0),
    "sphere15mm": lambda: sphere(15.0),
    "circle4mm": lambda: flat_circle(4.0),
    "circle8mm": lambda: flat_circle(8.0),
    "square": square,
    "ring": ring,
    "heart": heart,
    "woven": woven,
    "irregular": irregular,
    "ridged": ridged,
    "plate20mm": plate,
}


def get_indenter(name: str) -> Indenter:
    try:
        return INDENTERS[name]()
    except KeyError:
        raise KeyError(f"unknown indenter {name!r}; known: {', '.join(INDENTERS)}") from None
