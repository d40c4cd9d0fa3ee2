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
- every move runs inside the speed envelope (rig/envelope.py): no z below the depth
  guard's floor without ``allow_deep``, and each part of a move at a speed the guard can
  stop in time for the contact it may press (clamped with a note, or refused); while it
  runs, a first contact slows it, a measured stiffer contact slows it further, and the
  guard stops on the load predicted at the end of a stop, not only on the last reading;
- on any way out every axis is stopped. After an error or a signal z is also lifted
  clear whenever it may be pressed (rig/contact_state.py: averaged readings against the
  remembered unloaded reference, the remembered gel surface, the last load-free z;
  force-guarded at limits relaxed to the present load, or withdrawn open-loop and slowly
  when the gauge is gone), the gauge stream is stopped and the camera closed; a second
  signal during that sequence waits for it. ``on_stop`` receives the outcome.
"""
# Over 400 lines (564): the one guarded motion path (safety-critical): entry, moves, monitoring and the
# stop-and-lift exit share one session's state, and test_motion_guard lets only it and bounded.py send moves.

from __future__ import annotations

import logging
import math
from typing import Callable, Literal

import numpy as np

from rig.bounded import BoundedCommands
from rig.contact_state import CLEARANCE_MM, CONTACT_N, ContactTracker
from rig.device_floor import ControllerFloor
from rig.errors import (
    DeviceFault,
    DeviceTimeout,
    ForceLimitExceeded,
    RigError,
    SafetyError,
)
from rig.interruption import HANDLED_SIGNALS, MotionInterrupted, SignalsAsExceptions, StopReport, describe
from rig.lift import LiftAfterFailure
from rig.motion_envelope import EnvelopeWatch
from rig.move_plan import TOLERANCE_MM
from rig.safety import ForceGuard
from rig.types import WrenchGuard

log = logging.getLogger("rig.motion")

AXIS_MOTION_METHODS = ("move_to", "home")  # the Axis methods (rig/types.py) that start motion
SESSION_MODULES = ("rig/motion.py", "rig/bounded.py")  # the session and its command-issuing half: they alone send them
HOME_ORDER = ("z", "x", "y", "theta")  # z first: the indenter lifts clear before anything slides
MIN_POLLS_BEFORE_TIMEOUT = 50  # on a fast simulated clock one poll's exchanges can take seconds of clock time
WITHDRAW_SPEED = 0.5  # mm/s: z withdrawn open-loop (no gauge) no faster than this
REST_WAIT_S = 5.0  # how long a stop may brake before the stop sequence calls it a fault
__all__ = [
    "CLEARANCE_MM",
    "CONTACT_N",
    "HANDLED_SIGNALS",
    "Motion",
    "MotionInterrupted",
    "SignalsAsExceptions",
    "StopReport",
    "describe",
]

_active: list["Motion"] = []  # open sessions, for tests that check every motion happens inside one


def active_sessions() -> tuple["Motion", ...]:
    return tuple(_active)


class Motion(LiftAfterFailure, BoundedCommands, EnvelopeWatch):
    """One guarded motion session on ``rig``; get it from ``rig.motion(what, ...)``.

    ``on_start(text)`` is told when each move or homing has started (the CLI prints it);
    ``on_note(text)`` when the envelope clamps or slows a move (default: ``on_start``);
    ``on_stop(report)`` when the session ends. ``retract_to_z`` (axis mm): after an
    error lift z to there instead of searching for release. ``allow_deep``: z may go
    below the depth guard's floor, at the speed the window behind the gel allows.
    ``surface_hint`` (z, how): where the gel surface is said to be while the rig has none
    remembered (a protocol's origin); the first contact seen replaces it. ``search``: a z
    descent's target is only how far to look (find-contact): when a first contact puts it
    below the depth floor, z stops there instead of the session failing.
    """

    def __init__(
        self,
        rig,
        what: str,
        *,
        on_start: Callable[[str], None] | None = None,
        on_stop: Callable[[StopReport], None] | None = None,
        on_note: Callable[[str], None] | None = None,
        retract_to_z: float | None = None,
        allow_deep: bool = False,
        surface_hint: tuple[float, str] | None = None,
        search: bool = False,
        pending_signal: str | None = None,
    ):
        self.rig = rig
        self.what = what
        self.on_start = on_start
        self.on_stop = on_stop
        self.on_note = on_note if on_note is not None else on_start
        self.retract_to_z = retract_to_z
        self.allow_deep = allow_deep
        self.surface_hint = surface_hint
        self.search = search
        self.report: StopReport | None = None
        self._state = "new"  # new | open | closing | closed
        # Holding from the moment its handlers are in: a signal while the session opens (z may be
        # pressed from an earlier command) waits for the opening, then runs the stop sequence.
        self._signals = SignalsAsExceptions(holding=True)
        self._signals.held = pending_signal  # a signal that landed before the session (rig/signal_safety.py)
        self._guard: ForceGuard | None = None  # the guard of the latest move
        self._moving: set[str] = set()  # started and not yet seen idle
        self._idle_since: float | None = None  # clock time the last axis went idle, until a later wrench passed
        self._contact: ContactTracker | None = None
        self._poll_s = rig.config.safety.poll_s if rig.config.safety else 0.02  # the running move's check period
        self._commanded: dict[str, tuple[float, float]] = {}  # axis -> (the move's end, speed) under way
        self._issued: dict[str, float] = {}  # axis -> the target sent: the end, or short of it (rig/bounded.py)
        self._groups: list[set[str]] = []  # the axes of each move under way
        self._floor = ControllerFloor(rig) if "z" in rig.axes else None  # z's controller limit (rig/device_floor.py)
        self._pressing: list[tuple[float, float]] = []  # (z, raw Fz) while z presses, for dF/dz
        self._notes_said: set[str] = set()
        self._actions: list[str] = []
        self._slowed_s = 0.0  # time added to the running wait's deadline by slowing down
        self._move_started_s = -math.inf  # clock time the latest move started (its load rate starts there)
        self._strict = False  # the running move may not be slowed (a protocol's captured step)
        self._moved = False  # a motion command went out in this session
        self._previous: tuple[float, np.ndarray] | None = None  # the last check's reading, for a polled gauge's rate
        self._last_z_mm = math.inf  # z as last seen by a check

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
        rig.motion_session = self
        _active.append(self)
        self._state = "open"
        try:
            entry = rig.gauge.read_fresh()  # the gauge answers before anything moves
            rig.envelope()  # its timing measured (reads only) before the first move
            z_now = rig.axes["z"].position() if "z" in rig.axes else None
            self._contact = ContactTracker(rig, entry, z_now, self.surface_hint)
        except BaseException as exc:
            self.__exit__(type(exc), exc, exc.__traceback__)
            raise
        self._signals.holding = False
        if self._signals.held is not None:
            interrupted = MotionInterrupted(self._signals.held)
            self._signals.held = None
            self.__exit__(MotionInterrupted, interrupted, None)
            raise interrupted
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
            late = MotionInterrupted(held)
            late.secured = True  # it landed during the stop sequence, which then ran to its end
            raise late
        return False

    def _finish(self, exc: BaseException | None) -> BaseException | None:
        """The stop sequence. Returns an error found only now (an overload at the end)."""
        cleanup: list[str] = []
        unsettled = bool(self._moving) or self._idle_since is not None
        self._attempt(cleanup, "stop", self._stop_everything)
        if self._moved:  # a stop brakes: the lift and the final reading wait for the axes to rest
            self._attempt(cleanup, "waiting for the axes to stop", self._wait_at_rest)
        late_error = None
        if exc is None and unsettled:
            try:  # started without being waited for: the final wrench still has to pass
                (self._guard or self.rig.guard).check(self.rig.gauge.read_fresh())
            except Exception as error:
                late_error = error
        failure = exc if exc is not None else late_error
        if failure is not None:
            # A move refused before anything moved ("nothing was moved") leaves z where it was.
            refused = (
                not self._moved and isinstance(failure, SafetyError) and not isinstance(failure, ForceLimitExceeded)
            )
            if "z" in self.rig.axes and not refused:
                self._attempt(cleanup, "retract", lambda: self._lift_clear(failure))
        if self._floor is not None and self._floor.saved is not None:
            self._attempt(cleanup, "restoring z's controller travel limits", self._floor.release)
        if failure is not None:
            if getattr(self.rig.gauge, "streaming", False):
                self._attempt(cleanup, "stopping the gauge stream", self.rig.gauge.stop_stream)
            if self.rig.camera is not None:
                camera, self.rig.camera = self.rig.camera, None
                self._attempt(cleanup, "closing the camera", camera.close)
        if isinstance(failure, MotionInterrupted):
            failure.secured = True  # its stop sequence has run: no one needs to run another
        status, reason = describe(failure)
        self.report = StopReport(self.what, status, reason, failure, cleanup, list(self._actions))
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

    def _wait_at_rest(self) -> None:
        """Poll every axis until none reports busy (a stop command returns while the stage brakes)."""
        deadline = self.rig.clock.now() + REST_WAIT_S
        polls = 0
        while any(axis.status().busy for axis in self.rig.axes.values()):
            polls += 1
            if self.rig.clock.now() > deadline and polls > MIN_POLLS_BEFORE_TIMEOUT:
                raise DeviceTimeout(", ".join(self.rig.axes), "stop", None, "an axis still moves after its stop")
            self.rig.clock.sleep(self.rig.config.safety.poll_s)

    def _stop_everything(self) -> None:
        before = len(self.rig.stop_errors)
        self.rig.stop_all()
        self._moving.clear()
        self._commanded.clear()
        self._issued.clear()
        self._groups.clear()
        if len(self.rig.stop_errors) > before:
            raise self.rig.stop_errors[-1]

    def _withdraw_open_loop(self, target: float, here: float, why: str) -> None:
        """No gauge: z up to ``target`` slowly, watching only the axis (lifting cannot press)."""
        z = self.rig.axes["z"]
        cfg = self.rig.config.axes["z"]
        if target <= here + TOLERANCE_MM:
            return
        speed = min(cfg.jog_speed, cfg.max_speed, WITHDRAW_SPEED)
        self._moving.add("z")
        self._moved = True
        z.move_to(target, speed)
        deadline = self.rig.clock.now() + 5.0 + 2.0 * (target - here) / speed
        polls = 0
        while True:
            status = z.status()
            faults = z.faults(status)
            if faults:
                raise DeviceFault(z.label, "withdraw", status.warnings, ", ".join(faults))
            if not status.busy:
                break
            polls += 1
            if self.rig.clock.now() > deadline and polls > MIN_POLLS_BEFORE_TIMEOUT:
                raise DeviceTimeout(z.label, "withdraw", None, "z did not withdraw in time")
            self.rig.clock.sleep(self.rig.config.safety.poll_s)
        self._moving.discard("z")
        self._act(
            f"the gauge is gone: z withdrawn open-loop from {here:.3f} to {z.position():.3f} mm at {speed:g} mm/s "
            f"({why})"
        )

    # -- moving ---------------------------------------------------------------------------
    def _require_open(self) -> None:
        if self._state not in ("open", "closing"):
            raise SafetyError(
                f"motion session {self.what!r} is not open: the rig moves only inside `with rig.motion(...) as m:`"
            )

    def _note(self, text: str) -> None:
        if text not in self._notes_said:
            self._notes_said.add(text)
            if self.on_note is not None and self._state == "open":
                self.on_note(text)
            else:
                log.info("%s", text)

    def start_move(
        self,
        targets: dict[str, float],
        speed: float | dict[str, float] | None = None,
        *,
        poll_s: float | None = None,
        clamp: bool = True,
    ) -> ForceGuard:
        """Check, then start moving the axes to ``targets``; returns the guard to monitor with.

        ``poll_s``: how often the caller will ``monitor`` (the envelope's check period);
        ``clamp=False``: a speed above the envelope is refused (SpeedRefused) instead of
        clamped. The caller monitors until the axes are idle (``move`` does; ``settle`` waits).
        """
        self._require_open()
        poll = self._poll_for(poll_s)
        speeds = self.rig.check_targets(targets, speed)
        segments = self._plan(targets, speeds, poll, clamp, split=False)
        guard = self._start(*segments[0], poll)
        self._strict = not clamp
        return guard

    def _poll_for(self, poll_s: float | None) -> float:
        base = self.rig.config.safety.poll_s
        if poll_s is None:
            return base
        if not math.isfinite(poll_s) or poll_s <= 0:
            raise SafetyError(f"a check period must be finite and > 0 s, got {poll_s!r}")
        return max(base, poll_s)

    def _start(self, targets: dict[str, float], speeds: dict[str, float], poll_s: float | None = None) -> ForceGuard:
        guard, wrench = self._guard_for(targets)
        self._guard = guard
        self._poll_s = self._poll_for(poll_s)
        try:
            self._send(targets, speeds, wrench)
        except BaseException:
            self.rig.stop_all()
            raise
        self._idle_since = None
        self._pressing.clear()
        self._slowed_s = 0.0
        self._strict = False
        self._move_started_s = self.rig.clock.now()
        if "z" in targets:
            self._last_z_mm = self.rig.axes["z"].position()
        if self.on_start is not None and self._state == "open":
            cfg = self.rig.config.axes
            self.on_start(
                "; ".join(
                    f"{n}: moving to {round(t, 4) + 0.0:.4f} {cfg[n].unit} at {speeds[n]:g} {cfg[n].unit}/s"
                    for n, t in targets.items()
                )
            )
        return guard

    def _guard_for(self, targets: dict[str, float]):
        """(the guard for this move, the fresh reading it was chosen by). Over a limit already,
        only lifting z (+z is away from the gel) may start, guarded at the load it starts from so
        that it cannot grow."""
        wrench = self.rig.gauge.read_fresh()
        lifting = set(targets) == {"z"} and targets["z"] > self.rig.axes["z"].position()
        if lifting and np.all(np.isfinite(wrench.as_array())):
            # Going up can only unload the gel: guarded at the overshoot a stop may leave (the
            # envelope's margin) or the present load, whichever is higher, so that it cannot grow.
            margin = self.rig.config.safety.overshoot_margin
            relaxed = ForceGuard.from_limits(self.rig.guard.limits * (1.0 + margin))
            return relaxed.relaxed_to(wrench), wrench
        self.rig.guard.check(wrench)
        return self.rig.guard, wrench

    def monitor(self, names, guard: WrenchGuard | None = None, what: str | None = None) -> set[str]:
        """One safety check: the wrench against the limits (read and predicted), the axes for
        faults, and a z descent against the envelope (slowed or stopped at the depth floor).

        Returns the axes still moving; ``rig.last_status`` keeps what each reported.
        Once they are all idle, ``settled`` stays False until a wrench measured after
        that moment has passed. Raises ForceLimitExceeded, DepthLimitError or DeviceFault
        (the session stops the rig on the way out).
        """
        self._require_open()
        rig = self.rig
        guard = guard or rig.guard
        wrench = rig.gauge.read()
        guard.check(wrench)
        if self._moving:
            self._check_predicted(wrench, guard)
        latency_s = getattr(rig.gauge, "fresh_after_s", 0.0)
        if self._idle_since is not None and wrench.t_s - latency_s >= self._idle_since:
            self._idle_since = None
        moving = set()
        idle: set[str] = set()
        positions: dict[str, float] = {}
        z_seen = None
        for name in names:
            axis = rig.axes[name]
            status = axis.status()
            rig.last_status[name] = (rig.clock.now(), status)
            faults = axis.faults(status)
            if faults:
                raise DeviceFault(axis.label, what or self.what, status.warnings, ", ".join(faults))
            positions[name] = status.position
            if name == "z":
                z_seen = self._last_z_mm = status.position
            if status.busy or self._short(name):  # at rest short of its end (a bounded command): not done
                moving.add(name)
                if not status.busy:
                    idle.add(name)
            elif name in self._moving:
                self._moving.discard(name)
                self._commanded.pop(name, None)
                self._issued.pop(name, None)
                self._idle_since = rig.clock.now()
        if self._contact is not None and self._state == "open":
            commanded = self._commanded.get("z")
            descending = z_seen is not None and commanded is not None and commanded[0] < z_seen - TOLERANCE_MM
            if self._contact.observe(wrench, z_seen, descending, self.what):
                self._note(f"z: first contact at {z_seen:.4f} mm: remembered as the gel surface")
                if descending and self._floor is not None and self._floor.saved is not None:
                    self._floor.hold(self.controller_floor())  # the floor moves with the surface, in the controller too
            if z_seen is not None and "z" in moving:
                self._govern(z_seen, wrench)
        if self._issued and self._state in ("open", "closing"):
            self._rebound(positions, idle, wrench)
        return moving

    def time_left_s(self) -> float:
        """How long the started moves take from here at their commanded speeds (s)."""
        left = 0.0
        for name, (target, speed) in self._commanded.items():
            left = max(left, abs(target - self.rig.axes[name].position()) / speed)
        return left

    @property
    def slowed_s(self) -> float:
        """Time the running moves gained by being slowed since they started (a deadline moves by it)."""
        return self._slowed_s

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
                if self.rig.clock.now() > deadline + self._slowed_s and polls > MIN_POLLS_BEFORE_TIMEOUT:
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
        SafetyError, DepthLimitError); a speed above the envelope is clamped with a note.
        Raises ForceLimitExceeded, DeviceFault, DeviceTimeout.
        """
        self._require_open()
        rig = self.rig
        poll = rig.config.safety.poll_s
        speeds = rig.check_targets(targets, speed)
        for seg_targets, seg_speeds in self._plan(targets, speeds, poll, clamp=True):
            started = rig.clock.now()
            starts = {name: rig.axes[name].position() for name in seg_targets}
            guard = self._start(seg_targets, seg_speeds, poll)
            limit_s = timeout_s
            if limit_s is None:
                limit_s = 5.0 + 2.0 * max(abs(seg_targets[n] - starts[n]) / seg_speeds[n] for n in seg_targets)
            self._wait(tuple(seg_targets), started + limit_s, f"move to {targets}", guard)
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
        """Home the axes one at a time, z first, under the force guard. A lateral or twist
        axis does not home while the indenter is pressed (its homing speed is the device's,
        not the envelope's): z must lift first."""
        self._require_open()
        rig = self.rig
        names = tuple(rig.axes) if names is None else names
        rig.require_armed(names)
        for name in sorted(names, key=HOME_ORDER.index):
            if name != "z" and self._pressed_now():
                raise SafetyError(
                    f"axis {name}: not homing while the indenter is pressed (it would slide across the gel at the "
                    "device's homing speed); lift z first (rig home --axis z)"
                )
            # Homing z goes up, away from the gel: like a lift it may start from an overload.
            self._guard, _ = self._guard_for({name: float("inf")} if name == "z" else {name: 0.0})
            self._moving.add(name)
            self._moved = True
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
            if name == "z":
                rig.state.note_z_homed()  # a surface measured before this homing is unknown now
                if self._contact is not None:
                    self._contact.loaded = self._contact.is_loaded(rig.gauge.read())

    def stop(self) -> None:
        """Stop every axis now (a contact search stops at the touch)."""
        self.rig.stop_all()
        self._commanded.clear()
        self._issued.clear()
        self._groups.clear()
