"""A simulated motorised stage: position in mm (or deg) from its home switch.

Device simulators (Zaber, Modbus drive) translate their native units to and from
these physical units with the same scale a real device has.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

from rig.sim.motion import TrapezoidMove


@dataclass(frozen=True)
class StageSpec:
    travel: tuple[float, float]  # mechanical travel from home, mm or deg
    max_speed: float  # unit/s
    accel: float  # unit/s²
    home_position: float = 0.0  # where the home switch is


class StageFault(Exception):
    """The simulated stage cannot do what was asked (outside travel)."""


class SimStage:
    def __init__(self, name: str, spec: StageSpec, *, position: float = 0.0, homed: bool = True):
        lo, hi = spec.travel
        if not lo <= position <= hi:
            raise ValueError(f"stage {name}: start position {position} outside travel {spec.travel}")
        self.name = name
        self.spec = spec
        self._pos = position
        self._move: TrapezoidMove | None = None
        self.homed = homed
        self._homing = False
        self.stalled = False
        self.lock = threading.RLock()

    def _settle(self, t_s: float) -> None:
        if self._move is not None and self._move.done(t_s):
            self._pos = self._move.target
            self._move = None
            if self._homing:
                self._homing = False
                self.homed = True

    def position(self, t_s: float) -> float:
        with self.lock:
            self._settle(t_s)
            return self._move.position(t_s) if self._move is not None else self._pos

    def busy(self, t_s: float) -> bool:
        with self.lock:
            self._settle(t_s)
            return self._move is not None

    def move_to(self, target: float, speed: float, t_s: float) -> None:
        lo, hi = self.spec.travel
        if not lo <= target <= hi:
            raise StageFault(f"target {target} outside travel [{lo}, {hi}]")
        if speed <= 0:
            raise StageFault(f"speed {speed} must be > 0")
        with self.lock:
            if self.stalled:
                return  # a stalled motor does not move; the device reports the flag
            start = self.position(t_s)
            self._move = TrapezoidMove(start, target, min(speed, self.spec.max_speed), self.spec.accel, t_s)

    def stop(self, t_s: float) -> None:
        with self.lock:
            self._pos = self.position(t_s)
            self._move = None
            self._homing = False

    def home(self, t_s: float) -> None:
        with self.lock:
            self.move_to(self.spec.home_position, self.spec.max_speed, t_s)
            self._homing = True
            self.homed = False

    def stall(self, t_s: float) -> None:
        """Fault injection: the motor stalls where it is now."""
        with self.lock:
            self.stop(t_s)
            self.stalled = True

    def clear_stall(self) -> None:
        with self.lock:
            self.stalled = False
