"""Soft travel limits and the force/torque guard."""

from __future__ import annotations

import numpy as np

from rig.config import AxisConfig, SafetyConfig
from rig.errors import ForceLimitExceeded, SafetyError, SoftLimitError
from rig.types import WRENCH_COMPONENTS, WRENCH_UNITS, Wrench


def check_target(cfg: AxisConfig, target: float) -> None:
    """Raise SoftLimitError if ``target`` is outside the axis's configured travel."""
    low, high = cfg.travel
    if not np.isfinite(target) or not low <= target <= high:
        raise SoftLimitError(cfg.name, target, low, high, cfg.unit)


def check_speed(cfg: AxisConfig, speed: float) -> None:
    if not np.isfinite(speed) or not 0 < speed <= cfg.max_speed:
        raise SafetyError(
            f"axis {cfg.name}: speed {speed} {cfg.unit}/s is outside (0, {cfg.max_speed}] {cfg.unit}/s; "
            "nothing was moved"
        )


class ForceGuard:
    """Component-wise limits on |Fx|, |Fy|, |Fz| (N) and |Mx|, |My|, |Mz| (N·mm)."""

    def __init__(self, cfg: SafetyConfig):
        self.limits = np.array([*cfg.max_force_N, *cfg.max_torque_Nmm])

    @classmethod
    def from_limits(cls, limits: np.ndarray) -> "ForceGuard":
        guard = cls.__new__(cls)
        guard.limits = np.asarray(limits, dtype=float)
        return guard

    def relaxed_to(self, wrench: Wrench, margin: float = 0.05) -> "ForceGuard":
        """Limits raised to the present load (+5 %) where it exceeds them: for a retract."""
        return ForceGuard.from_limits(np.maximum(self.limits, np.abs(wrench.as_array()) * (1 + margin)))

    def check(self, wrench: Wrench) -> None:
        values = wrench.as_array()
        over = np.abs(values) > self.limits
        if not np.all(np.isfinite(values)):
            raise ForceLimitExceeded("wrench", float("nan"), 0.0, "(not finite)")
        if over.any():
            i = int(np.argmax(np.abs(values) / self.limits))
            raise ForceLimitExceeded(WRENCH_COMPONENTS[i], float(values[i]), float(self.limits[i]), WRENCH_UNITS[i])
