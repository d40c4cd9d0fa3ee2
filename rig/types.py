"""The small typed interfaces every device of a kind satisfies.

Positions are in mm for linear axes and degrees for rotary ones; wrenches are
[Fx, Fy, Fz] in N and [Mx, My, Mz] in N·mm; times are seconds on the host's
monotonic clock (or the injected clock).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

WRENCH_COMPONENTS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
WRENCH_UNITS = ("N", "N", "N", "N·mm", "N·mm", "N·mm")


@dataclass(frozen=True)
class Wrench:
    """One host-timestamped six-axis sample: forces in N, moments in N·mm."""

    t_s: float
    fx_N: float
    fy_N: float
    fz_N: float
    mx_Nmm: float
    my_Nmm: float
    mz_Nmm: float

    def as_array(self) -> np.ndarray:
        return np.array(
            [self.fx_N, self.fy_N, self.fz_N, self.mx_Nmm, self.my_Nmm, self.mz_Nmm], dtype=np.float64
        )

    @classmethod
    def from_array(cls, t_s: float, values) -> "Wrench":
        v = [float(x) for x in values]
        if len(v) != 6:
            raise ValueError(f"a wrench has 6 components, got {len(v)}")
        return cls(t_s, *v)

    def minus(self, bias: np.ndarray) -> "Wrench":
        return Wrench.from_array(self.t_s, self.as_array() - bias)


class MotionState(enum.Enum):
    IDLE = "idle"
    BUSY = "busy"


@dataclass(frozen=True)
class AxisStatus:
    """What an axis reports about itself."""

    position: float
    state: MotionState
    homed: bool
    warnings: tuple[str, ...] = field(default=())

    @property
    def busy(self) -> bool:
        return self.state is MotionState.BUSY


@dataclass(frozen=True)
class Frame:
    """A tactile camera frame, stamped with the host clock at arrival."""

    t_s: float
    index: int
    image: np.ndarray  # (H, W, 3) uint8, BGR as OpenCV delivers it


@runtime_checkable
class Axis(Protocol):
    """A linear (mm) or rotary (deg) stage axis."""

    name: str
    unit: str

    def position(self) -> float: ...

    def status(self) -> AxisStatus: ...

    def move_to(self, target: float, speed: float) -> None:
        """Start a move to ``target`` at ``speed`` (unit/s); returns once accepted."""

    def stop(self) -> None: ...

    def home(self) -> None:
        """Start homing; returns once accepted."""

    def close(self) -> None: ...


@runtime_checkable
class ForceGauge(Protocol):
    """A six-axis force/torque gauge."""

    name: str

    def read(self) -> Wrench:
        """A fresh tared sample (polled, or the newest streamed one)."""

    def tare(self, n_samples: int = 20) -> np.ndarray:
        """Average ``n_samples`` and subtract that bias from later reads; returns the bias."""

    def close(self) -> None: ...


@runtime_checkable
class Camera(Protocol):
    name: str

    def read(self, timeout_s: float = 1.0) -> Frame:
        """The newest frame not returned before; raises DeviceTimeout if none arrives."""

    def close(self) -> None: ...
