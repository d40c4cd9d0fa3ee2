"""The small typed interfaces every device of a kind satisfies, and the rig's.

Positions are in mm for linear axes and degrees for rotary ones; wrenches are
[Fx, Fy, Fz] in N and [Mx, My, Mz] in N·mm; times are seconds on the host's
monotonic clock (or the injected clock).

Devices satisfy these ``typing.Protocol``s structurally (no base class): ``Axis``
(ZaberAxis, PrDriveAxis), ``ForceGauge`` and ``StreamingGauge`` (FT300, M8128,
AtiNetFT), ``Camera`` (rig.drivers.camera.Camera over V4L2, a folder, a video or the
simulated camera). ``RigLike`` is what the layers above the rig (the executor, the
CLI) use of ``rig.rig.Rig``, with ``MotionSession`` and ``WrenchGuard`` for the parts
it hands out. tests/test_protocols_conform.py checks each driver against its protocol.
Errors named here are rig.errors types.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

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
        return np.array([self.fx_N, self.fy_N, self.fz_N, self.mx_Nmm, self.my_Nmm, self.mz_Nmm], dtype=np.float64)

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


@dataclass
class RigStatus:
    """What ``rig status`` shows: each open axis's status, and the tared wrench (None without a gauge)."""

    axes: dict[str, AxisStatus]
    wrench: Wrench | None


@runtime_checkable
class Axis(Protocol):
    """A linear (mm) or rotary (deg) stage axis; ``unit`` says which ("mm" or "deg").

    Every method may raise DeviceTimeout, FramingError or DeviceDisconnected when the
    exchange with the device fails, and DeviceRejected when the device refuses it.
    """

    name: str  # the rig's name for it: "x", "y", "z", "theta"
    unit: str  # "mm" or "deg": the unit of every position and speed below
    label: str  # for messages: the name, the driver and the port

    def position(self) -> float:
        """The present position (unit)."""
        ...

    def status(self) -> AxisStatus:
        """Position (unit), busy or idle, referenced or not, and the device's warning flags."""
        ...

    def faults(self, status: AxisStatus) -> list[str]:
        """The warnings of ``status`` that are faults (stop the motion), each with its meaning; [] if none."""
        ...

    def move_to(self, target: float, speed: float) -> None:
        """Start a move to ``target`` (unit) at ``speed`` (unit/s); returns once accepted."""
        ...

    def stop(self) -> None:
        """Decelerate to a stop now; returns once accepted."""
        ...

    def home(self) -> None:
        """Start homing; returns once accepted."""
        ...

    def close(self) -> None:
        """Release what this axis alone owns (a shared port stays open for its chain)."""
        ...


@runtime_checkable
class ForceGauge(Protocol):
    """A six-axis force/torque gauge, polled: wrenches in N and N·mm, host-stamped (s).

    Reads raise DeviceTimeout, FramingError or DeviceDisconnected when the device does
    not answer properly, DeviceFault when it reports a fault of its own.
    """

    name: str
    label: str  # for messages: the name, the model and the port

    @property
    def bias(self) -> np.ndarray:
        """The (6,) tare subtracted from every read (N, N·mm); zeros until ``tare``."""
        ...

    @property
    def fresh_after_s(self) -> float:
        """Bound (s) on the time from measurement to arrival: how old a new sample can be."""
        ...

    def read(self) -> Wrench:
        """A tared sample: polled now, or the newest streamed one (fetched anew when stale)."""
        ...

    def read_fresh(self) -> Wrench:
        """A tared sample measured after this call (waits up to ``fresh_after_s`` when streaming)."""
        ...

    def sample_at(self, t_s: float, timeout_s: float = 2.0) -> tuple[np.ndarray, float]:
        """The (6,) tared wrench at clock time ``t_s`` (N, N·mm) and the skew (s) to the nearest sample.

        Streaming: interpolated between the samples around ``t_s``, waiting (bounded by
        ``timeout_s``) for one stamped at or after it; raises DeviceTimeout if none comes.
        Polled: one read now.
        """
        ...

    def tare(self, n_samples: int = 20) -> np.ndarray:
        """Average ``n_samples`` untared samples, subtract that from later reads; returns the (6,) bias."""
        ...

    def close(self) -> None:
        """Stop streaming if it streams and release the port."""
        ...


@runtime_checkable
class StreamingGauge(ForceGauge, Protocol):
    """A gauge that can also stream (~100 Hz or more) into a timestamped buffer."""

    @property
    def streaming(self) -> bool:
        """True between ``start_stream`` and ``stop_stream``."""
        ...

    def start_stream(self) -> None:
        """Start streaming; reads then come from the buffer. A no-op when already streaming."""
        ...

    def stop_stream(self) -> None:
        """Stop streaming and drain what was in flight; reads poll again. A no-op when not streaming."""
        ...

    def stream_stats(self) -> dict[str, Any]:
        """Counters since the stream started: samples, frames_bad, bytes_skipped (and per-driver ones)."""
        ...


@runtime_checkable
class Camera(Protocol):
    """A tactile camera delivering ``Frame``s (BGR uint8, host-stamped at exposure or arrival, s)."""

    name: str

    def trigger(self) -> None:
        """Ask a triggered source for one frame; a no-op for free-running cameras."""
        ...

    def read(self, timeout_s: float = 1.0) -> Frame:
        """The newest frame not returned before, waiting up to ``timeout_s`` (s).

        Raises DeviceTimeout if none arrives in time, DeviceDisconnected if the source
        failed or ended (unplugged, end of a recording).
        """
        ...

    def close(self) -> None:
        """Stop grabbing and release the source."""
        ...


@runtime_checkable
class WrenchGuard(Protocol):
    """Force/torque limits a wrench is checked against (rig.safety.ForceGuard)."""

    @property
    def limits(self) -> np.ndarray:
        """(6,) limits on |Fx|, |Fy|, |Fz| (N) and |Mx|, |My|, |Mz| (N·mm)."""
        ...

    def check(self, wrench: Wrench) -> None:
        """Raise ForceLimitExceeded naming the component if ``wrench`` is over a limit or not finite."""
        ...


@runtime_checkable
class MotionSession(Protocol):
    """A guarded motion session (rig.motion.Motion): the only way to move the rig.

    Every move is checked before anything moves (SoftLimitError, SafetyError); while
    it runs it raises ForceLimitExceeded, DeviceFault or DeviceTimeout, and on any way
    out of the session every axis is stopped. Positions in each axis's unit (mm, deg),
    speeds in unit/s (one for all axes, per axis, or None: each axis's jog speed).
    """

    @property
    def settled(self) -> bool:
        """Every started axis seen idle and a wrench measured after that within the limits."""
        ...

    def move(
        self,
        targets: dict[str, float],
        speed: float | dict[str, float] | None = None,
        *,
        timeout_s: float | None = None,
    ) -> dict[str, float]:
        """Move the axes together to absolute ``targets`` and wait; returns the final positions."""
        ...

    def start_move(
        self,
        targets: dict[str, float],
        speed: float | dict[str, float] | None = None,
        *,
        poll_s: float | None = None,
        clamp: bool = True,
    ) -> WrenchGuard:
        """Start a move without waiting; returns the guard to ``monitor`` it with. ``poll_s``:
        how often the caller monitors; ``clamp=False``: a speed over the envelope is refused."""
        ...

    def monitor(self, names: Any, guard: WrenchGuard | None = None, what: str | None = None) -> set[str]:
        """One check of the wrench and of the axes ``names`` (an iterable); returns those still moving."""
        ...

    def settle(self, names: Any, guard: WrenchGuard | None = None, *, timeout_s: float = 120.0) -> None:
        """Monitor until ``names`` are idle and a later wrench passed; DeviceTimeout after ``timeout_s``."""
        ...

    def jog(
        self, axis: str, *, step: float | None = None, to: float | None = None, speed: float | None = None
    ) -> float:
        """Move one axis by ``step`` or to ``to``; returns where it ended. RigError unless exactly one."""
        ...

    def home_axes(self, names: tuple[str, ...] | None = None, *, timeout_s: float = 120.0) -> None:
        """Home the axes one at a time, z first; DeviceFault if one ends unreferenced."""
        ...

    def stop(self) -> None:
        """Stop every axis now."""
        ...


@runtime_checkable
class ClockLike(Protocol):
    """The rig's clock (rig.clock.Clock, restated here: rig.types sits below rig.clock in the layers)."""

    def now(self) -> float:
        """Monotonic time (s)."""
        ...

    def sleep(self, dt_s: float) -> None:
        """Wait ``dt_s`` seconds of this clock's time."""
        ...


@runtime_checkable
class RigLike(Protocol):
    """What the layers above the rig (acquisition's executor, the CLI) use of ``rig.rig.Rig``."""

    @property
    def config(self) -> Any:
        """The rig.config.RigConfig it was opened from (typed there: the config sits above rig.types)."""
        ...

    @property
    def clock(self) -> ClockLike: ...

    @property
    def axes(self) -> Mapping[str, Axis]:
        """The open axes by name ("x", "y", "z", "theta")."""
        ...

    @property
    def gauge(self) -> ForceGauge | None: ...

    @property
    def camera(self) -> Camera | None: ...

    @property
    def guard(self) -> WrenchGuard | None:
        """The configured limits; None without a [safety] section (nothing may move then)."""
        ...

    @property
    def last_status(self) -> dict[str, tuple[float, AxisStatus]]:
        """(clock time s, status) each axis last reported to a monitor."""
        ...

    def positions(self) -> dict[str, float]:
        """Every open axis's position (its unit). Raises the axes' DeviceErrors."""
        ...

    def status(self) -> RigStatus:
        """Every open axis's status and a wrench (None without a gauge)."""
        ...

    def tare(self, n_samples: int = 20) -> np.ndarray:
        """Tare the gauge; returns the (6,) bias (N, N·mm). RigError without a gauge."""
        ...

    def motion(
        self,
        what: str,
        *,
        on_start: Callable[[str], None] | None = None,
        on_stop: Callable[[Any], None] | None = None,
        retract_to_z: float | None = None,
    ) -> AbstractContextManager[MotionSession]:
        """The one way to move: ``with rig.motion("jog") as m: m.move(...)``.

        Entering raises SafetyError unless a gauge with finite limits is open and answers.
        """
        ...
