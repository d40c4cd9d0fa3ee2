"""The gel: modulus, Poisson ratio, thickness, friction. Units: MPa (= N/mm²), mm."""

from __future__ import annotations

import math
from dataclasses import dataclass


class PhysicsInputError(ValueError):
    """An input that has no physical meaning (negative modulus, ν ≥ 0.5, ...)."""


@dataclass(frozen=True)
class Elastomer:
    E_MPa: float = 0.25  # Young's modulus: soft silicone gels are 0.1–1 MPa
    nu: float = 0.48  # Poisson ratio: gels are nearly incompressible
    thickness_mm: float = 3.0  # bonded to a rigid (acrylic) window; math.inf = half-space
    friction: float = 1.0  # Coulomb coefficient gel/indenter (silicone is grippy)

    def __post_init__(self):
        if not (math.isfinite(self.E_MPa) and self.E_MPa > 0):
            raise PhysicsInputError(f"elastomer modulus E_MPa must be a finite number > 0, got {self.E_MPa}")
        if not (-1.0 < self.nu <= 0.5):
            raise PhysicsInputError(f"Poisson ratio nu must be in (-1, 0.5], got {self.nu}")
        if not self.thickness_mm > 0:
            raise PhysicsInputError(f"thickness_mm must be > 0 (math.inf for a half-space), got {self.thickness_mm}")
        if not (math.isfinite(self.friction) and self.friction >= 0):
            raise PhysicsInputError(f"friction must be a finite number >= 0, got {self.friction}")

    @property
    def E_star_MPa(self) -> float:
        """Plane-strain modulus E/(1-ν²) of the gel against a rigid indenter."""
        return self.E_MPa / (1.0 - self.nu**2)

    @property
    def G_MPa(self) -> float:
        return self.E_MPa / (2.0 * (1.0 + self.nu))
