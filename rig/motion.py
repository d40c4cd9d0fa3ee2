"""The one way to move the rig: a motion session.

    with rig.motion("jog") as m:
        m.move({"z": -1.0}, 0.5)

The rig has no move methods of its own; only a session sends ``move_to`` or
``home`` to an axis, and tests/test_motion_guard.py fails if any other module does.
A session guarantees (docs/safety.md):

- the force and torque limits are armed before the first byte goes out: a gauge
  with finite limits must be open and give a fresh reading, or nothing starts;
- a wait ends only when every axis is idle *and* a wrench measured after the last
  axis went idle is within the limits (a streamed sample can predate the end of
  the travel, and the last ``poll_s`` of a press is where the force grows fastest);
- SIGINT, SIGTERM and SIGHUP raise ``MotionInterrupted`` naming the signal;
- on any way out every axis is stopped. After an error or a signal z is also lifted
  clear when the gauge says it touches something (force-guarded, at limits relaxed
  to the present load), the gauge stream is stopped and the camera closed; a second
  signal during that sequence waits for it. ``on_stop`` receives the outcome.
"""

from __future__ import annotations

import logging
import signal
import threading
from dataclasses import dataclass, field
from types import FrameType
from typing import Any, Callable, Literal

import numpy as np

from rig.errors import DeviceFault, DeviceTimeout, ForceLimitExceeded, RigError, SafetyError
from rig.safety import ForceGuard
from rig.types import WrenchGuard

log = logging.getLogger("rig.motion")

AXIS_MOTION_METHODS = ("move_to", "home")  # the Axis methods (rig/types.py) that start motion
HANDLED_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")  # Ctrl-C, kill/systemd, a closed terminal or SSH session
HOME_ORDER = ("z", "x", "y", "theta")  # z first: the indenter lifts clear before anything slides
MIN_POLLS_BEFORE_TIMEOUT = 50  # on a fast simulated clock one poll's exchanges can take seconds of clock time
CONTACT_N = 0.05  # |ΔFz| that means touching: find-contact's default threshold, >10σ of gauge noise
LIFT_MAX_MM = 5.0  # how far an error lift searches for release: beyond any gel the rig takes (3 mm)
CLEARANCE_MM = 0.5  # lifted this far past the point where the load went away

_active: list["Motion"] = []  # open sessions, for tests that check every motion happens inside one


def active_sessions() -> tuple["Motion", ...]:
    return tuple(_active)


class MotionInterrupted(KeyboardInterrupt):
    """A signal stopped the motion; ``signal_name`` says which (SIGINT, SIGTERM, SIGHUP)."""

    def __init__(self, signal_name: str):
        self.signal_name = signal_name
        super().__init__(signal_name)

    @property
    def exit_code(self) -> int:
        """The shell convention for death by this signal: 128 + its number (SIGTERM 143, SIGHUP 129)."""
        return 128 + int(getattr(signal, self.signal_name))


def describe(exc: BaseException | None) -> tuple[str, str]:
    """(status, reason) for how a session ended: complete, interrupted (SIGTERM), aborted: Type: message."""
    if exc is None:
        return "complete", ""
    if isinstance(exc, MotionInterrupted):
        return "interrupted", f"interrupted ({exc.signal_name})"
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted", "interrupted (Ctrl-C)"
    return "aborted", f"aborted: {type(exc).__name__}: {exc}"


class SignalsAsExceptions:
    """While entered (main thread only; elsewhere Python cannot install handlers), the
    handled signals raise ``MotionInterrupted``; with ``holding`` set they are only noted
    in ``held``. The previous handlers come back on exit."""

    def __init__(self):
        self._previous: dict[int, Callable[[int, FrameType | None], Any] | int | None] = {}
        self.holding = False
        self.held: str | None = None

    def __enter__(self) -> "SignalsAsExceptions":
        if threading.current_thread() is threading.main_thread():
            for name in HANDLED_SIGNALS:
                number = getattr(signal, name, None)
                if number is not None:
                    self._previous[number] = signal.signal(number, self._handle)
        return self

    def _handle(self, signum, _frame) -> None:
        name = signal.Signals(signum).name
        if self.holding:
            self.held = self.held or name
            return
        raise MotionInterrupted(name)

    def __exit__(self, *exc) -> None:
        for number, previous in self._previous.items():
            # None: a handler installed from C, which Python cannot reinstate; the default is the safe fallback.
            signal.signal(number, previous if previous is not None else signal.SIG_DFL)
        self._previous.clear()


@dataclass
class StopReport:
    """How a session ended, for ``on_stop`` (the acquisition writes it into the run file)."""

    what: str
    status: str  # complete | aborted | interrupted
    reason: str  # "" when complete
    error: BaseException | None
    cleanup_errors: list[str] = field(default_factory=list)  # a stop, lift or close that failed


class Motion:
    """One guarded motion session on ``rig``; get it from ``rig.motion(what, ...)``.

    ``on_start(text)`` is told when each move or homing has started (the CLI prints it);
    ``on_stop(report)`` when the session ends. ``retract_to_z`` (axis mm): after an
    error lift z to there instead of searching for release.
    """

    def __init__(
        self,
        rig,
        what: str,
        *,
        on_start: Callable[[str], None] | None = None,
        on_stop: Callable[[StopReport], None] | None = None,
        retract_to_z: float | None = None,
    ):
        self.rig = rig
        self.what = what
        self.on_start = on_start
        self.on_stop = on_stop
        self.retract_to_z = retract_to_z
        self.report: StopReport | None = None
        self._state = "new"  # new | open | closing | closed
        self._signals = SignalsAsExceptions()
        self._guard: ForceGuard | None = None  # the guard of the latest move
        self._moving: set[str] = set()  # started and not yet seen idle
        self._idle_since: float | None = None  # clock time the last axis went idle, until a later wrench passed
        self._entry_fz_N = 0.0

    # -- entering and leaving --------------------------------------------------------
    def __enter__(self) -> "Motion":
        rig = self.rig
        if self._state != "new":
            raise SafetyError(f"motion session {self.what!r} was already used; open a new one")
        if rig.motion_session is not None:
            raise SafetyError(f"motion session {rig.motion_session.what!r} is already open on this rig")
        rig.require_armed(())
        limits = rig.guard.limits
        if not np.all(np.isfinite(limits)) or np.any(limits <= 0):
            raise SafetyError(
                f"refusing to move: force/torque limits {limits.tolist()} are not all finite and > 0 "
                f"(config {rig.config.path} [safety])"
            )
        self._signals.__enter__()
        try:
            self._entry_fz_N = rig.gauge.read_fresh().fz_N  # the gauge answers before anything moves
        except BaseException:
            self._signals.__exit__()
            raise
        rig.motion_session = self
        _active.append(self)
        self._state = "open"
        return self

    def __exit__(self, exc_type, exc, tb) -> Literal[False]:
        self._signals.holding = True  # a second signal must not cut the stop sequence short
        self._state = "closing"
        try:
            late_error = self._finish(exc)
        finally:
            self._state = "closed"
            self.rig.motion_session = None
            _active.remove(self)
            held = self._signals.held
            self._signals.__exit__()
        if exc is None and late_error is not None:
            raise late_error
        if exc is None and held is not None:
            raise MotionInterrupted(held)
        return False

    def _finish(self, exc: BaseException | None) -> BaseException | None:
        """The stop sequence. Returns an error found only now (an overload at the end)."""
        cleanup: list[str] = []
        unsettled = bool(self._moving) or self._idle_since is not None
        self._attempt(cleanup, "stop", self._stop_everything)
        late_error = None
        if exc is None and unsettled:
            try:  # started without being waited for: the final wrench still has to pass
                (self._guard or self.rig.guard).check(self.rig.gauge.read_fresh())
            except Exception as error:
                late_error = error
        failure = exc if exc is not None else late_error
        if failure is not None:
            if "z" in self.rig.axes:
                self._attempt(cleanup, "retract", self._lift_clear)
            if getattr(self.rig.gauge, "streaming", False):
                self._attempt(cleanup, "stopping the gauge stream", self.rig.gauge.stop_stream)
            if self.rig.camera is not None:
                camera, self.rig.camera = self.rig.camera, None
                self._attempt(cleanup, "closing the camera", camera.close)
        status, reason = describe(failure)
        self.report = StopReport(self.what, status, reason, failure, cleanup)
        if self.on_stop is not None:
            try:
                self.on_stop(self.report)
            except Exception as error:  # the motion is already safe; the original error must not be replaced
                log.error("recording how %s ended failed: %s", self.what, error)
        return late_error

    def _attempt(self, cleanup: list[str], what: str, action) -> None:
        """One step of the stop sequence; a failure is kept and logged, and the next step still runs."""
        try:
            action()
        except Exception as exc:
            cleanup.append(f"{what} failed: {exc}")
            log.error("%s after %s: %s", what, self.what, exc)

    def _stop_everything(self) -> None:
        before = len(self.rig.stop_errors)
        self.rig.stop_all()
        self._moving.clear()
        if len(self.rig.stop_errors) > before:
            raise self.rig.stop_errors[-1]

    def _in_contact(self, wrench) -> bool:
        tared = np.any(getattr(self.rig.gauge, "bias", np.zeros(6)) != 0)
        unloaded = 0.0 if tared else self._entry_fz_N
        try:
            self.rig.guard.check(wrench)
        except ForceLimitExceeded:
            return True
        return abs(wrench.fz_N - unloaded) >= CONTACT_N

    def _lift_clear(self) -> None:
        """After an error: z up to ``retract_to_z``, or until the load goes away plus CLEARANCE_MM."""
        z = self.rig.axes["z"]
        cfg = self.rig.config.axes["z"]
        here = z.position()
        if self.retract_to_z is not None:
            if here < self.retract_to_z - 1e-6:
                self.move({"z": self.retract_to_z}, cfg.jog_speed)
            return
        if not self._in_contact(self.rig.gauge.read_fresh()):
            return
        top = min(cfg.travel[1], here + LIFT_MAX_MM)
        guard = self._start({"z": top}, {"z": cfg.jog_speed})
        deadline = self.rig.clock.now() + 5.0 + 2.0 * (top - here) / cfg.jog_speed
        polls = 0
        while self._in_contact(self.rig.gauge.read()):
            if not self.monitor(("z",), guard, "lift clear") and self._idle_since is None:
                raise SafetyError(f"z lifted to {top:.3f} mm and the gauge still reads a load; lift it by hand")
            polls += 1
            if self.rig.clock.now() > deadline and polls > MIN_POLLS_BEFORE_TIMEOUT:
                raise DeviceTimeout(z.label, "lift clear", None, "z did not lift clear in time")
            self.rig.clock.sleep(self.rig.config.safety.poll_s)
        self.rig.stop_all()
        released = z.position()
        self.move({"z": min(top, released + CLEARANCE_MM)}, cfg.jog_speed)

    # -- moving ---------------------------------------------------------------------------
    def _require_open(self) -> None:
        if self._state not in ("open", "closing"):
            raise SafetyError(
                f"motion session {self.what!r} is not open: the rig moves only inside `with rig.motion(...) as m:`"
            )

    def start_move(self, targets: dict[str, float], speed: float | dict[str, float] | None = None) -> ForceGuard:
        """Check, then start moving the axes to ``targets``; returns the guard to monitor with.

        The caller monitors until the axes are idle (``move`` does; ``settle`` waits).
        """
        self._require_open()
        return self._start(targets, self.rig.check_targets(targets, speed))

    def _start(self, targets: dict[str, float], speeds: dict[str, float]) -> ForceGuard:
        guard = self._guard_for(targets)
        self._guard = guard
        try:
            for name, target in targets.items():
                self._moving.add(name)
                self.rig.axes[name].move_to(target, speeds[name])
        except BaseException:
            self.rig.stop_all()
            raise
        self._idle_since = None
        if self.on_start is not None and self._state == "open":
            cfg = self.rig.config.axes
            self.on_start(
                "; ".join(
                    f"{n}: moving to {t:.4f} {cfg[n].unit} at {speeds[n]:g} {cfg[n].unit}/s" for n, t in targets.items()
                )
            )
        return guard

    def _guard_for(self, targets: dict[str, float]) -> ForceGuard:
        """The guard for this move. Over a limit already, only lifting z (+z is away from
        the gel) may start, guarded at the load it starts from so that it cannot grow."""
        wrench = self.rig.gauge.read_fresh()
        try:
            self.rig.guard.check(wrench)
            return self.rig.guard
        except ForceLimitExceeded:
            lifting = set(targets) == {"z"} and targets["z"] > self.rig.axes["z"].position()
            if not lifting:
                raise
            return self.rig.guard.relaxed_to(wrench)

    def monitor(self, names, guard: WrenchGuard | None = None, what: str | None = None) -> set[str]:
        """One safety check: the wrench against the limits, the axes for faults.

        Returns the axes still moving; ``rig.last_status`` keeps what each reported.
        Once they are all idle, ``settled`` stays False until a wrench measured after
        that moment has passed. Raises ForceLimitExceeded or DeviceFault (the session
        stops the rig on the way out).
        """
        self._require_open()
        rig = self.rig
        guard = guard or rig.guard
        wrench = rig.gauge.read()
        guard.check(wrench)
        latency_s = getattr(rig.gauge, "fresh_after_s", 0.0)
        if self._idle_since is not None and wrench.t_s - latency_s >= self._idle_since:
            self._idle_since = None
        moving = set()
        for name in names:
            axis = rig.axes[name]
            status = axis.status()
            rig.last_status[name] = (rig.clock.now(), status)
            faults = axis.faults(status)
            if faults:
                raise DeviceFault(axis.label, what or self.what, status.warnings, ", ".join(faults))
            if status.busy:
                moving.add(name)
            elif name in self._moving:
                self._moving.discard(name)
                self._idle_since = rig.clock.now()
        return moving

    @property
    def settled(self) -> bool:
        """Every started axis seen idle and a wrench measured after that within the limits."""
        return not self._moving and self._idle_since is None

    def settle(self, names, guard: WrenchGuard | None = None, *, timeout_s: float = 120.0) -> None:
        """Monitor until ``names`` are idle and a wrench measured after that has passed."""
        self._wait(tuple(names), self.rig.clock.now() + timeout_s, self.what, guard)

    def _wait(self, names: tuple[str, ...], deadline: float, what: str, guard: WrenchGuard | None = None) -> None:
        """Poll until settled. Any error stops every axis before it propagates: a caller
        may catch a refused step (interactive jogging) and go on inside the session."""
        polls = 0
        try:
            while self.monitor(names, guard, what) or self._idle_since is not None:
                polls += 1
                if self.rig.clock.now() > deadline and polls > MIN_POLLS_BEFORE_TIMEOUT:
                    raise DeviceTimeout(", ".join(names), what, None, "motion did not finish in time")
                self.rig.clock.sleep(self.rig.config.safety.poll_s)
        except BaseException:
            self.rig.stop_all()
            raise

    def move(
        self,
        targets: dict[str, float],
        speed: float | dict[str, float] | None = None,
        *,
        timeout_s: float | None = None,
    ) -> dict[str, float]:
        """Move the given axes together to absolute ``targets``; returns the final positions.

        Every target and speed is checked before anything moves (SoftLimitError,
        SafetyError). Raises ForceLimitExceeded, DeviceFault, DeviceTimeout.
        """
        self._require_open()
        rig = self.rig
        speeds = rig.check_targets(targets, speed)
        started = rig.clock.now()
        starts = {name: rig.axes[name].position() for name in targets}
        guard = self._start(targets, speeds)
        if timeout_s is None:
            timeout_s = 5.0 + 2.0 * max(abs(targets[n] - starts[n]) / speeds[n] for n in targets)
        self._wait(tuple(targets), started + timeout_s, f"move to {targets}", guard)
        final = {name: rig.axes[name].position() for name in targets}
        for name, target in targets.items():
            cfg = rig.config.axes[name]
            if abs(final[name] - target) > rig.tolerance(name):
                rig.last_targets.pop(name, None)
                raise DeviceFault(
                    rig.axes[name].label,
                    f"move to {target}",
                    final[name],
                    f"stopped at {final[name]:.5f} {cfg.unit}, not at the target {target:.5f} {cfg.unit}",
                )
            rig.last_targets[name] = target
        return final

    def jog(
        self, axis: str, *, step: float | None = None, to: float | None = None, speed: float | None = None
    ) -> float:
        """Move one axis by ``step`` or to ``to`` (mm or deg); returns where it ended."""
        if (step is None) == (to is None):
            raise RigError("jog needs exactly one of step or to")
        self._require_open()
        self.rig.require_armed((axis,))
        if to is not None:
            return self.move({axis: to}, speed)[axis]
        # Step from the last target while the axis still sits there, so that repeated
        # steps do not accumulate the native-unit rounding of each one.
        here = self.rig.axes[axis].position()
        last = self.rig.last_targets.get(axis)
        base = last if last is not None and abs(here - last) <= self.rig.tolerance(axis) else here
        return self.move({axis: base + step}, speed)[axis]

    def home_axes(self, names: tuple[str, ...] | None = None, *, timeout_s: float = 120.0) -> None:
        """Home the axes one at a time, z first, under the force guard."""
        self._require_open()
        rig = self.rig
        names = tuple(rig.axes) if names is None else names
        rig.require_armed(names)
        for name in sorted(names, key=HOME_ORDER.index):
            # Homing z goes up, away from the gel: like a lift it may start from an overload.
            self._guard = self._guard_for({name: float("inf")} if name == "z" else {name: 0.0})
            self._moving.add(name)
            rig.axes[name].home()
            self._idle_since = None
            if self.on_start is not None:
                self.on_start(f"{name}: homing")
            self._wait((name,), rig.clock.now() + timeout_s, "home", self._guard)
            status = rig.axes[name].status()
            if not status.homed:
                raise DeviceFault(
                    rig.axes[name].label, "home", status, "homing finished but the axis is not referenced"
                )

    def stop(self) -> None:
        """Stop every axis now (a contact search stops at the touch)."""
        self.rig.stop_all()
