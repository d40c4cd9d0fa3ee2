"""Where the indenter is: its pose relative to the contact point."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Pose:
    """Indenter pose relative to the contact point: mm, mm, mm (negative = pressed in), deg."""

    x_mm: float
    y_mm: float
    z_mm: float
    theta_deg: float

    @property
    def depth_mm(self) -> float:
        return max(0.0, -self.z_mm)
