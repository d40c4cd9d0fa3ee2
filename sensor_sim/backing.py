"""The rigid window under the gel: what an indentation past the gel thickness does.

The gel (thickness t) is bonded to an acrylic window. With the approach d > t, the
part of the indenter face lower than d − t above its tip (separation h < d − t) has
squeezed the gel to nothing and presses on the window:

- the gel takes the indenter's shape clipped at the window: its sink is
  min(d − h, t), i.e. the gel solve sees the separation max(h, d − t). The gel's
  deformation (the image) is the deepest it can take under that face, and it keeps
  spreading continuously as more of the face reaches the window;
- the window carries the rest through the indenter–window contact. Its incremental
  stiffness is that of a rigid punch of the overlapping area A on an elastic
  half-space, dF/dδ = 2E*·√(A/π) (Sneddon 1965; Pharr, Oliver & Brotzen 1992 for any
  face shape), integrated over the overlap δ = d − t from the height map. Exact for
  a flat face; for a sphere the geometric overlap is twice Hertz's contact area, so
  the force is √2 × Hertz's (an upper bound, steep as the real contact).

E* is a steel indenter on an acrylic window: ≈ 3.6 GPa, so an 8 mm flat face adds
~29 N per µm. Force is continuous and monotonic in d through t, the gauge sees a
steep but finite rise, and the rig's force guard trips as on hardware.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

WINDOW_E_MPa = 3.2e3  # cast acrylic (PMMA) window, 2.4–3.3 GPa
WINDOW_NU = 0.35
INDENTER_E_MPa = 2.0e5  # steel indenter
INDENTER_NU = 0.30
WINDOW_E_STAR_MPa = 1.0 / ((1 - WINDOW_NU**2) / WINDOW_E_MPa + (1 - INDENTER_NU**2) / INDENTER_E_MPa)


@dataclass(frozen=True)
class BackingLoad:
    force_N: float  # carried by the window, pressing it down
    stiffness_N_per_mm: float  # dF/dδ at this overlap
    area_mm2: float  # indenter face past the window plane
    x_mm: float  # where the load acts (overlap-weighted centroid)
    y_mm: float


NO_BACKING = BackingLoad(0.0, 0.0, 0.0, 0.0, 0.0)


def gel_separation(h_mm: np.ndarray, depth_mm: float, thickness_mm: float) -> np.ndarray:
    """The separation the gel solve sees: the indenter face clipped at the window."""
    overlap_mm = depth_mm - thickness_mm
    return np.maximum(h_mm, overlap_mm) if overlap_mm > 0 else h_mm


def backing_load(
    h_mm: np.ndarray,
    X_mm: np.ndarray,
    Y_mm: np.ndarray,
    overlap_mm: float,
    cell_mm2: float,
    e_star_MPa: float = WINDOW_E_STAR_MPa,
) -> BackingLoad:
    """Load on the window for the face ``h_mm`` (on the pad grid) past it by ``overlap_mm``."""
    if not overlap_mm > 0:
        return NO_BACKING
    past = h_mm < overlap_mm
    if not past.any():
        return NO_BACKING
    # Each cell reaches the window at δ = h: the area is cell·k between the k-th and
    # (k+1)-th sorted heights, so the integral of 2E*√(A/π) dδ is a finite sum.
    meets = np.sort(h_mm[past])
    counts = np.arange(1, meets.size + 1)
    spans = np.append(meets[1:], overlap_mm) - meets
    scale = 2.0 * e_star_MPa / math.sqrt(math.pi)
    force = scale * float(np.sum(np.sqrt(counts * cell_mm2) * spans))
    area = meets.size * cell_mm2
    weight = overlap_mm - h_mm[past]  # deeper parts of the face press harder
    total = float(weight.sum())
    if total > 0:
        x, y = float((X_mm[past] * weight).sum()) / total, float((Y_mm[past] * weight).sum()) / total
    else:
        x, y = float(X_mm[past].mean()), float(Y_mm[past].mean())
    return BackingLoad(force, scale * math.sqrt(area), area, x, y)
