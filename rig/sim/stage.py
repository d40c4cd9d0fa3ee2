"""A simulated motorised stage: position in mm (or deg) from its home switch.

Device simulators (Zaber, Modbus drive) translate their native units to and from
these physical units with the same scale a real device has, and set the stage's
dynamics to their device's (``SimStage.configure``). The stage has a velocity at every
instant: a new target mid-move starts from the current position and velocity, and a
stop is a deceleration ramp after the device's reaction time, not a jump
(docs/simulator.md, "Stopping").
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, replace

from rig.sim.motion import Profile, move_profile, stop_profile


@dataclass(frozen=True)
class StageSpec:
    """Travel and dynamics; unit = mm or deg, as the stage's position."""

    travel: tuple[float, float]  # mechanical travel from home
    max_speed: float  # unit/s
    accel: float  # unit/s², a move speeding up (and slowing down, unless ``decel``)
    home_position: float = 0.0  # where the home switch is
    decel: float = 0.0  # unit/s², a move slowing down; 0: ``accel``
    stop_decel: float = 0.0  # unit/s², a stop command's ramp; 0: the move's ``decel``
    stop_reaction_s: float = 0.0  # from a stop command's last byte to the start of its ramp
    abrupt_decel: float = 0.0  # unit/s², an emergency stop (Zaber `estop`); 0: ``stop_decel``

    def __post_init__(self):
        if self.max_speed <= 0 or self.accel <= 0:
            raise ValueError(f"max_speed and accel must be > 0, got {self.max_speed}, {self.accel}")
        if min(self.decel, self.stop_decel, self.abrupt_decel, self.stop_reaction_s) < 0:
            raise ValueError("decel, stop_decel, abrupt_decel and stop_reaction_s must be >= 0")

    @property
    def move_decel(self) -> float:
        return self.decel or self.accel


@dataclass(frozen=True)
class Stopping:
    """How a stage comes to rest on a stop, as its device does it (read-only, for the rig)."""

    decel: float  # unit/s², a stop command
    reaction_s: float  # command processing before the ramp starts (wire time is the host's)
    abrupt_decel: float  # unit/s², an emergency stop

    def distance(self, speed: float, *, abrupt: bool = False) -> float:
        """How far a stage moving at ``speed`` travels after the stop command."""
        decel = self.abrupt_decel if abrupt else self.decel
        return self.reaction_s * abs(speed) + speed * speed / (2 * decel)


class StageFault(Exception):
    """The simulated stage cannot do what was asked (outside travel)."""


class SimStage:
    """One stage. Asked at the times a clock gives (never before a time it has been asked
    at once a move has ended: the move is then forgotten)."""

    def __init__(self, name: str, spec: StageSpec, *, position: float = 0.0, homed: bool = True):
        lo, hi = spec.travel
        if not lo <= position <= hi:
            raise ValueError(f"stage {name}: start position {position} outside travel {spec.travel}")
        self.name = name
        self.spec = spec
        self._pos = position
        self._move: Profile | None = None
        self.homed = homed
        self.commanded_speed: float | None = None  # the speed of the latest move command
        self._homing = False
        self.stalled = False
        self.lock = threading.RLock()

    def configure(
        self,
        *,
        accel: float | None = None,
        decel: float | None = None,
        stop_decel: float | None = None,
        stop_reaction_s: float | None = None,
        abrupt_decel: float | None = None,
    ) -> None:
        """Set the device's dynamics (those given; unit/s², s); a move already under way
        keeps its profile."""
        with self.lock:
            s = self.spec
            self.spec = replace(
                s,
                accel=s.accel if accel is None else accel,
                decel=s.decel if decel is None else decel,
                stop_decel=s.stop_decel if stop_decel is None else stop_decel,
                stop_reaction_s=s.stop_reaction_s if stop_reaction_s is None else stop_reaction_s,
                abrupt_decel=s.abrupt_decel if abrupt_decel is None else abrupt_decel,
            )

    @property
    def stopping(self) -> Stopping:
        spec = self.spec
        decel = spec.stop_decel or spec.move_decel
        return Stopping(decel, spec.stop_reaction_s, spec.abrupt_decel or decel)

    def _settle(self, t_s: float) -> None:
        if self._move is not None and t_s >= self._move.t_end_s:
            self._pos = self._move.end
            self._move = None
            if self._homing:
                self._homing = False
                self.homed = True

    def position(self, t_s: float) -> float:
        with self.lock:
            move = self._move
            if move is None:
                return self._pos
            if t_s >= move.t_end_s:
                self._settle(t_s)
                return self._pos
            return move.position(t_s)

    def velocity(self, t_s: float) -> float:
        with self.lock:
            self._settle(t_s)
            return self._move.velocity(t_s) if self._move is not None else 0.0

    @property
    def target(self) -> float | None:
        """Where the move under way ends (a stop's end while braking); None at rest."""
        with self.lock:
            return None if self._move is None else self._move.end

    def busy(self, t_s: float) -> bool:
        """True until the stage is at rest (a stop's reaction and ramp included)."""
        with self.lock:
            self._settle(t_s)
            return self._move is not None

    def move_to(self, target: float, speed: float, t_s: float) -> None:
        """Go to ``target`` at up to ``speed`` from where the stage is now, at the speed it
        has now (reversing through zero if the target is behind), on the spec's ramps."""
        lo, hi = self.spec.travel
        if not lo <= target <= hi:
            raise StageFault(f"target {target} outside travel [{lo}, {hi}]")
        if speed <= 0:
            raise StageFault(f"speed {speed} must be > 0")
        with self.lock:
            if self.stalled:
                return  # a stalled motor does not move; the device reports the flag
            self._settle(t_s)
            spec = self.spec
            here = self._move.position(t_s) if self._move is not None else self._pos
            v0 = self._move.velocity(t_s) if self._move is not None else 0.0
            v_max = min(speed, spec.max_speed)
            self.commanded_speed = speed
            self._move = move_profile(here, v0, target, v_max, spec.accel, spec.move_decel, t_s)
            self._homing = False

    def stop(self, t_s: float, *, abrupt: bool = False) -> None:
        """A stop command at ``t_s``: the stage goes on as it was for the reaction time,
        then slows to rest at the stop deceleration (``abrupt``: the emergency one).
        Busy until at rest."""
        with self.lock:
            self._settle(t_s)
            self._homing = False
            if self._move is None:
                return
            stopping = self.stopping
            ramp = stopping.abrupt_decel if abrupt else stopping.decel
            ramp = max(ramp, self._decel_to_stay_in_travel(t_s + stopping.reaction_s))
            self._move = self._move.then(t_s + stopping.reaction_s, lambda x, v, t: stop_profile(x, v, ramp, t))

    def _decel_to_stay_in_travel(self, t_s: float) -> float:
        """The deceleration that stops at the travel's end (a limit switch), if the stop
        ramp would otherwise run past it; 0 when it does not."""
        assert self._move is not None
        x, v = self._move.position(t_s), self._move.velocity(t_s)
        lo, hi = self.spec.travel
        room = (hi - x) if v > 0 else (x - lo)
        return v * v / (2 * room) if room > 0 and v != 0 else 0.0

    def home(self, t_s: float) -> None:
        with self.lock:
            self.move_to(self.spec.home_position, self.spec.max_speed, t_s)
            self._homing = True
            self.homed = False

    def stall(self, t_s: float) -> None:
        """Fault injection: the motor stalls where it is now, at once (no ramp)."""
        with self.lock:
            self._settle(t_s)
            if self._move is not None:
                self._pos = self._move.position(t_s)
            self._move = None
            self._homing = False
            self.stalled = True

    def clear_stall(self) -> None:
        with self.lock:
            self.stalled = False
