"""Stage motion as a pure function of time: phases of constant acceleration.

A ``Profile`` holds phases, each starting at ``t0_s`` from position ``x0`` and velocity
``v0`` with a constant acceleration; after the last one the stage rests at ``end``
(from ``t_end_s``). Position and velocity are continuous across phases. Builders:

- ``move_profile``: from a resting *or moving* start to rest at a target, cruising at up
  to ``v_max``, speeding up at ``accel`` and slowing down at ``decel`` (a trapezoid, or a
  triangle when the move is short). A start moving away from the target, or too fast
  to stop before it, first slows to zero and reverses through it.
- ``stop_profile``: slows from the current velocity to rest at ``decel``.
- ``Profile.then``: this profile until ``t_s``, then another starting from its state
  there (a stop or a new target mid-move).

Units are the caller's (mm or deg, seconds). ``position(t)`` is the simulated rig's hot
path (every gauge sample and frame asks every stage): one comparison at rest, a
``bisect`` over at most five phases while moving.
"""

from __future__ import annotations

import math
from bisect import bisect_right

_EPS_S = 1e-12  # phases shorter than this are dropped (float noise of a zero-length ramp)


class Profile:
    """Phases ``(t0_s, x0, v0, a)``, ascending in time; at rest at ``end`` from ``t_end_s``."""

    __slots__ = ("_t0", "_x0", "_v0", "_a", "end", "t_end_s")

    def __init__(self, phases: list[tuple[float, float, float, float]], end: float, t_end_s: float):
        if not phases:
            raise ValueError("a profile needs at least one phase")
        self._t0 = tuple(p[0] for p in phases)
        self._x0 = tuple(p[1] for p in phases)
        self._v0 = tuple(p[2] for p in phases)
        self._a = tuple(p[3] for p in phases)
        self.end = end
        self.t_end_s = t_end_s

    @property
    def t0_s(self) -> float:
        return self._t0[0]

    @property
    def start(self) -> float:
        return self._x0[0]

    @property
    def duration_s(self) -> float:
        return self.t_end_s - self._t0[0]

    def done(self, t_s: float) -> bool:
        return t_s >= self.t_end_s

    def position(self, t_s: float) -> float:
        if t_s >= self.t_end_s:
            return self.end
        i = bisect_right(self._t0, t_s) - 1
        if i < 0:
            return self._x0[0]
        dt = t_s - self._t0[i]
        return self._x0[i] + (self._v0[i] + 0.5 * self._a[i] * dt) * dt

    def velocity(self, t_s: float) -> float:
        if t_s >= self.t_end_s:
            return 0.0
        i = bisect_right(self._t0, t_s) - 1
        if i < 0:
            return self._v0[0]
        return self._v0[i] + self._a[i] * (t_s - self._t0[i])

    def phases(self) -> list[tuple[float, float, float, float]]:
        return list(zip(self._t0, self._x0, self._v0, self._a))

    def then(self, t_s: float, follow) -> "Profile":
        """This profile until ``t_s``, then ``follow(x, v, t_s)`` (a Profile, or None to
        keep this one: nothing changes) from the state this one has at ``t_s``."""
        if t_s >= self.t_end_s:
            return self  # already at rest by then: a later command starts from rest itself
        nxt = follow(self.position(t_s), self.velocity(t_s), t_s)
        if nxt is None:
            return self
        kept = [p for p in self.phases() if p[0] < t_s - _EPS_S]
        return Profile(kept + nxt.phases(), nxt.end, nxt.t_end_s)


def _build(x0: float, v0: float, t0_s: float, ramps: list[tuple[float, float]]) -> Profile:
    """Phases from (x0, v0) at t0_s, each ``(duration_s, acceleration)``; zero-length ones dropped."""
    phases = []
    t, x, v = t0_s, x0, v0
    for duration_s, a in ramps:
        if duration_s <= _EPS_S:
            continue
        phases.append((t, x, v, a))
        x += (v + 0.5 * a * duration_s) * duration_s
        v += a * duration_s
        t += duration_s
    if not phases:
        phases.append((t0_s, x0, 0.0, 0.0))
    return Profile(phases, x, t)


def stop_profile(x0: float, v0: float, decel: float, t0_s: float) -> Profile:
    """From velocity ``v0`` to rest at ``decel``: v0/decel seconds, v0²/(2·decel) further on."""
    if decel <= 0:
        raise ValueError(f"deceleration must be > 0, got {decel}")
    profile = _build(x0, v0, t0_s, [(abs(v0) / decel, -math.copysign(decel, v0))])
    # the end exactly as the closed form has it (the phase arithmetic may round differently)
    profile.end = x0 + v0 * abs(v0) / (2 * decel)
    return profile


def move_profile(x0: float, v0: float, target: float, v_max: float, accel: float, decel: float, t0_s: float) -> Profile:
    """From (x0, v0) at t0_s to rest at ``target``; |v| ≤ max(v_max, |v0|) throughout."""
    if v_max <= 0 or accel <= 0 or decel <= 0:
        raise ValueError(f"speed, acceleration and deceleration must be > 0, got {v_max}, {accel}, {decel}")
    d = target - x0
    stopping = v0 * abs(v0) / (2 * decel)  # signed distance to rest from v0
    if v0 != 0 and (v0 * d < 0 or abs(stopping) > abs(d)):
        # moving away, or too fast to stop before the target: to rest first, then back
        first = stop_profile(x0, v0, decel, t0_s)
        rest = move_profile(first.end, 0.0, target, v_max, accel, decel, first.t_end_s)
        return Profile(first.phases() + rest.phases(), target, rest.t_end_s)
    if d == 0:
        return _build(x0, 0.0, t0_s, [])
    sign = 1.0 if d > 0 else -1.0
    length, u = abs(d), abs(v0)
    if u > v_max:  # slower cruise than now: slow to v_max, cruise, slow to rest
        down = (u - v_max) / decel
        cruise = (length - u * u / (2 * decel)) / v_max
        ramps = [(down, -decel), (cruise, 0.0), (v_max / decel, -decel)]
    else:
        # peak speed of an accelerate-then-decelerate over ``length`` from u
        peak = math.sqrt((2 * accel * decel * length + decel * u * u) / (accel + decel))
        cruise = 0.0
        if peak > v_max:
            peak = v_max
            cruise = (length - (v_max * v_max - u * u) / (2 * accel) - v_max * v_max / (2 * decel)) / v_max
        ramps = [((peak - u) / accel, accel), (cruise, 0.0), (peak / decel, -decel)]
    profile = _build(x0, v0, t0_s, [(duration, sign * a) for duration, a in ramps])
    profile.end = target  # exactly the target, whatever the rounding of the phases
    return profile
