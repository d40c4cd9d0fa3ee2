"""The rig: the configured axes, gauge and camera, with safety armed on every move.

No method moves a stage unless the axis has soft limits and a force gauge with
limits is open and reading. While anything moves, the wrench is checked every
``safety.poll_s``; a limit trip, a device fault, a timeout or Ctrl-C stops every
axis before the error propagates.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from rig.clock import Clock, SystemClock
from rig.config import RigConfig
from rig.errors import DeviceError, DeviceFault, DeviceTimeout, ForceLimitExceeded, RigError, SafetyError
from rig.factory import PortPool, open_axis, open_camera, open_gauge
from rig.safety import ForceGuard, check_speed, check_target
from rig.types import AxisStatus, Wrench

log = logging.getLogger("rig")
HOME_ORDER = ("z", "x", "y", "theta")
MIN_POLLS_BEFORE_TIMEOUT = 50  # lift the indenter clear before anything slides


@dataclass
class RigStatus:
    axes: dict[str, AxisStatus]
    wrench: Wrench | None


class Rig:
    def __init__(self, config: RigConfig, clock: Clock, *, axes: dict, gauge=None, camera=None,
                 pool: PortPool | None = None):
        self.config = config
        self.clock = clock
        self.axes = axes
        self.gauge = gauge
        self.camera = camera
        self._pool = pool
        self.guard = ForceGuard(config.safety) if config.safety else None
        self.stop_errors: list[DeviceError] = []
        self._targets: dict[str, float] = {}  # last target each axis reached
        self.last_status: dict[str, tuple[float, AxisStatus]] = {}  # (clock time, status) from monitor

    @classmethod
    def open(cls, config: RigConfig, clock: Clock | None = None, *, axes: tuple[str, ...] | None = None,
             gauge: bool = True, camera: bool = False, sim=None) -> "Rig":
        """Open only the devices asked for (``axes=None``: all configured axes)."""
        clock = clock or SystemClock()
        names = tuple(config.axes) if axes is None else axes
        for name in names:
            if name not in config.axes:
                raise RigError(f"{config.path}: axis {name!r} is not configured (configured: {', '.join(config.axes) or 'none'})")
        pool = PortPool()
        opened_gauge = opened_camera = None
        opened_axes = {}
        try:
            for name in names:
                opened_axes[name] = open_axis(config.axes[name], pool)
            if gauge and config.gauge is not None:
                opened_gauge = open_gauge(config.gauge, clock, pool)
            if camera:
                if config.camera is None:
                    raise RigError(f"{config.path}: no [camera] section")
                opened_camera = open_camera(config.camera, clock, sim)
        except BaseException:
            if opened_gauge is not None:
                opened_gauge.close()
            pool.close()
            raise
        return cls(config, clock, axes=opened_axes, gauge=opened_gauge, camera=opened_camera, pool=pool)

    # -- reading ----------------------------------------------------------------
    def positions(self) -> dict[str, float]:
        return {name: axis.position() for name, axis in self.axes.items()}

    def status(self) -> RigStatus:
        return RigStatus(axes={n: a.status() for n, a in self.axes.items()},
                         wrench=self.gauge.read() if self.gauge is not None else None)

    def tare(self, n_samples: int = 20):
        if self.gauge is None:
            raise RigError("no force gauge open")
        return self.gauge.tare(n_samples)

    # -- moving -----------------------------------------------------------------
    def _require_armed(self, names) -> None:
        if self.gauge is None or self.guard is None:
            raise SafetyError("refusing to move: no force gauge with limits is armed "
                              f"(config {self.config.path} needs [gauge] and [safety])")
        for name in names:
            if name not in self.axes:
                raise RigError(f"axis {name!r} is not open")

    def check_targets(self, targets: dict[str, float], speed: float | dict[str, float] | None = None) -> dict[str, float]:
        """Soft-limit and speed checks for a move; returns the per-axis speeds. Moves nothing."""
        self._require_armed(targets)
        speeds = {}
        for name, target in targets.items():
            cfg = self.config.axes[name]
            check_target(cfg, target)
            s = speed.get(name, cfg.jog_speed) if isinstance(speed, dict) else (cfg.jog_speed if speed is None else speed)
            check_speed(cfg, s)
            speeds[name] = s
        return speeds

    def start_move(self, targets: dict[str, float], speed: float | dict[str, float] | None = None) -> ForceGuard:
        """Check, then start moving the axes to ``targets``; returns the guard to monitor with.

        The caller must call ``monitor`` until the axes are idle (``move`` does).
        """
        return self._start(targets, self.check_targets(targets, speed))

    def _start(self, targets: dict[str, float], speeds: dict[str, float]) -> ForceGuard:
        """Start checked moves; returns the guard to monitor with."""
        guard = self._guard_for(targets)
        try:
            for name, target in targets.items():
                self.axes[name].move_to(target, speeds[name])
        except BaseException:
            self.stop_all()
            raise
        return guard

    def monitor(self, names, guard: ForceGuard | None = None, what: str = "move") -> set[str]:
        """One safety check: the wrench against the limits, the axes for faults.

        Returns the axes still moving; ``last_status`` keeps what each axis reported.
        Raises ForceLimitExceeded or DeviceFault (the caller stops the rig).
        """
        (guard or self.guard).check(self.gauge.read())
        moving = set()
        for name in names:
            axis = self.axes[name]
            status = axis.status()
            self.last_status[name] = (self.clock.now(), status)
            faults = axis.faults(status)
            if faults:
                raise DeviceFault(axis.label, what, status.warnings, ", ".join(faults))
            if status.busy:
                moving.add(name)
        return moving

    def move(self, targets: dict[str, float], speed: float | dict[str, float] | None = None,
             *, timeout_s: float | None = None) -> dict[str, float]:
        """Move the given axes together to absolute ``targets``; returns the final positions.

        Every target and speed is checked before anything moves (SoftLimitError,
        SafetyError). Raises ForceLimitExceeded, DeviceFault, DeviceTimeout after
        stopping all axes.
        """
        speeds = self.check_targets(targets, speed)
        started = self.clock.now()
        try:
            starts = {name: self.axes[name].position() for name in targets}
            guard = self._start(targets, speeds)
            if timeout_s is None:
                timeout_s = 5.0 + 2.0 * max(abs(targets[n] - starts[n]) / speeds[n] for n in targets)
            self._wait(tuple(targets), started + timeout_s, f"move to {targets}", guard)
        except BaseException:
            self.stop_all()
            raise
        final = {name: self.axes[name].position() for name in targets}
        for name, target in targets.items():
            cfg = self.config.axes[name]
            if abs(final[name] - target) > self._tolerance(name):
                self._targets.pop(name, None)
                raise DeviceFault(self.axes[name].label, f"move to {target}", final[name],
                                  f"stopped at {final[name]:.5f} {cfg.unit}, not at the target {target:.5f} {cfg.unit}")
            self._targets[name] = target
        return final

    def _tolerance(self, name: str) -> float:
        return max(1e-4, 2 * abs(getattr(self.axes[name], "scale", 0.0)))

    def jog(self, axis: str, *, step: float | None = None, to: float | None = None,
            speed: float | None = None) -> float:
        if (step is None) == (to is None):
            raise RigError("jog needs exactly one of step or to")
        self._require_armed((axis,))
        if to is not None:
            return self.move({axis: to}, speed)[axis]
        # Step from the last target while the axis still sits there, so that repeated
        # steps do not accumulate the native-unit rounding of each one.
        here = self.axes[axis].position()
        last = self._targets.get(axis)
        base = last if last is not None and abs(here - last) <= self._tolerance(axis) else here
        return self.move({axis: base + step}, speed)[axis]

    def home(self, names: tuple[str, ...] | None = None, *, timeout_s: float = 120.0) -> None:
        """Home the axes one at a time, z first, under the force guard."""
        names = tuple(self.axes) if names is None else names
        self._require_armed(names)
        for name in sorted(names, key=HOME_ORDER.index):
            try:
                self.axes[name].home()
                self._wait((name,), self.clock.now() + timeout_s, "home")
            except BaseException:
                self.stop_all()
                raise
            status = self.axes[name].status()
            if not status.homed:
                raise DeviceFault(self.axes[name].label, "home", status, "homing finished but the axis is not referenced")

    def _guard_for(self, targets: dict[str, float]) -> ForceGuard:
        """The guard for this move. Over a limit already, only lifting z (+z is away from
        the gel) may start, guarded at the load it starts from so that it cannot grow."""
        wrench = self.gauge.read_fresh()
        try:
            self.guard.check(wrench)
            return self.guard
        except ForceLimitExceeded:
            lifting = set(targets) == {"z"} and targets["z"] > self.axes["z"].position()
            if not lifting:
                raise
            return self.guard.relaxed_to(wrench)

    def _wait(self, names: tuple[str, ...], deadline: float, what: str, guard: ForceGuard | None = None) -> None:
        poll_s = self.config.safety.poll_s
        polls = 0
        while self.monitor(names, guard, what):
            polls += 1
            # Both the deadline and a minimum of polls: on a fast simulated clock one
            # poll's serial exchanges can take seconds of clock time.
            if self.clock.now() > deadline and polls > MIN_POLLS_BEFORE_TIMEOUT:
                raise DeviceTimeout(", ".join(names), what, None, "motion did not finish in time")
            self.clock.sleep(poll_s)

    def stop_all(self) -> None:
        """Stop every axis; a failure to stop one is logged and kept, never hidden."""
        for axis in self.axes.values():
            try:
                axis.stop()
            except DeviceError as exc:
                self.stop_errors.append(exc)
                log.error("could not stop %s: %s", axis.label, exc)

    # -- lifetime ---------------------------------------------------------------
    def close(self) -> None:
        if self.camera is not None:
            self.camera.close()
        if self.gauge is not None:
            try:
                self.gauge.close()
            except DeviceError as exc:
                log.error("closing the gauge: %s", exc)
        if self._pool is not None:
            self._pool.close()

    def __enter__(self) -> "Rig":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
