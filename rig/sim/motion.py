"""Trapezoidal (or triangular) point-to-point motion, as a pure function of time."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class TrapezoidMove:
    """A move from ``start`` to ``target`` at up to ``v_max`` with acceleration ``accel``.

    Units are whatever the caller uses (mm, deg); ``t0_s`` is when it began.
    """

    start: float
    target: float
    v_max: float
    accel: float
    t0_s: float

    def __post_init__(self):
        if self.v_max <= 0 or self.accel <= 0:
            raise ValueError(f"speed and acceleration must be > 0, got {self.v_max}, {self.accel}")

    @property
    def distance(self) -> float:
        return abs(self.target - self.start)

    @property
    def _profile(self) -> tuple[float, float, float]:
        """(peak speed, ramp time, cruise time)."""
        d = self.distance
        t_ramp = self.v_max / self.accel
        if self.accel * t_ramp * t_ramp >= d:  # never reaches v_max: triangular
            t_ramp = math.sqrt(d / self.accel)
            return self.accel * t_ramp, t_ramp, 0.0
        return self.v_max, t_ramp, (d - self.accel * t_ramp * t_ramp) / self.v_max

    @property
    def duration_s(self) -> float:
        _, t_ramp, t_cruise = self._profile
        return 2 * t_ramp + t_cruise

    def done(self, t_s: float) -> bool:
        return t_s - self.t0_s >= self.duration_s

    def position(self, t_s: float) -> float:
        t = t_s - self.t0_s
        if t <= 0:
            return self.start
        v_peak, t_ramp, t_cruise = self._profile
        sign = 1.0 if self.target >= self.start else -1.0
        if t >= 2 * t_ramp + t_cruise:
            return self.target
        if t < t_ramp:
            s = 0.5 * self.accel * t * t
        elif t < t_ramp + t_cruise:
            s = 0.5 * self.accel * t_ramp * t_ramp + v_peak * (t - t_ramp)
        else:
            td = 2 * t_ramp + t_cruise - t
            s = self.distance - 0.5 * self.accel * td * td
        return self.start + sign * s
