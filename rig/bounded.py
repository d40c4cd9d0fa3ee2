"""Bounded commands: no command in or near contact reaches further than the guard can afford
(docs/safety.md, "Bounded commands").

The force guard stops a move when the host sees a load at its limit. A host that stops answering
(frozen, killed, starved) sees nothing, and the stage runs on to the target it was last given.
So while an axis may press, the target sent to it is not the move's end but the nearest point
of the way there at which the load could reach the limit, given the load read now, the
contact's worst-case (or measured) stiffness and how far the axis goes before that reading is
old: for z, ``(limit − |Fz|) / stiffness − speed × (gauge period + latency)``,
and, while no load is seen yet, no further than the depth guard's depth below where z is now
(the gel cannot begin below an unloaded indenter). Sideways and twisting axes while pressed take
the shear and twist stiffnesses and limits. Each check re-issues the target further on (or
nearer, when the load grew faster than assumed), so a move runs on at its speed as long as the
host answers, and stops where it is safe when it does not.

Near contact starts ``surface_uncertainty_mm`` + the clearance above the remembered surface (the
real gel may be that much higher), and everywhere when the surface is not known.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rig.contact_state import CLEARANCE_MM, ContactTracker
from rig.errors import ForceLimitExceeded
from rig.move_plan import TOLERANCE_MM

EXTEND_FRACTION = 0.5  # a target is re-issued further on once less than this share of its reach is left


class BoundedCommands:
    """The command-issuing half of a motion session (rig/motion.py): ``_send`` and ``_rebound``."""

    rig: Any
    allow_deep: bool
    surface_hint: tuple[float, str] | None
    _contact: ContactTracker | None
    _commanded: dict[str, tuple[float, float]]  # axis -> (the move's end, speed)
    _issued: dict[str, float]  # axis -> the target last sent (the end, or short of it)
    _groups: list[set[str]]  # the axes of each move under way: one move's axes keep to one path
    _moving: set[str]
    _moved: bool
    _poll_s: float
    _floor: Any  # rig/device_floor.py ControllerFloor, or None without z

    # -- where z may go -------------------------------------------------------------------------
    def approach_top(self) -> float:
        """Above this z the indenter cannot be near the gel: the remembered surface plus its
        uncertainty and the clearance; +inf while no surface is known."""
        guard = self.rig.depth_guard(self.surface_hint)
        if guard is None:
            return math.inf
        return guard.surface_z + self.rig.config.safety.surface_uncertainty_mm + CLEARANCE_MM

    def controller_floor(self) -> float:
        """The lowest z the controller is to allow in this session: the depth floor (the window with
        ``allow_deep``), else the configured travel's end while no surface is known."""
        guard = self.rig.depth_guard(self.surface_hint)
        if guard is None:
            return self.rig.config.axes["z"].travel[0]
        return guard.window_z if self.allow_deep else guard.floor_z

    def _reach(self, name: str, here: float, speed: float, wrench, pressed: bool) -> float:
        """How far ``name`` may go from ``here`` in one command (its unit); inf: unbounded."""
        rig = self.rig
        envelope = rig.envelope()
        safety = rig.config.safety
        limits = rig.guard.limits
        values = np.abs(wrench.as_array()) if wrench is not None else np.zeros(6)
        # the reading is this old: the axis went on meanwhile (a stop is not part of it: a frozen
        # host sends none, and the stage stops at the target on its own ramp)
        lag = envelope.timing.gauge_period_s + envelope.timing.gauge_latency_s
        if name == "z":
            guard = rig.depth_guard(self.surface_hint)
            deep = guard is not None and here < guard.floor_z + TOLERANCE_MM
            k = safety.window_stiffness_N_per_mm if deep and self.allow_deep else envelope.normal_stiffness()[0]
            reach = (limits[2] - values[2]) / k - speed * lag
            loaded = self._contact is not None and self._contact.loaded
            if not loaded and safety.gel_thickness_mm is not None:
                reach = min(reach, safety.max_depth_fraction * safety.gel_thickness_mm)
            return max(0.0, reach)
        if not pressed:
            return math.inf
        if name == "theta":
            return max(0.0, (limits[5] - values[5]) / safety.twist_stiffness_Nmm_per_deg - speed * lag)
        i = 0 if name == "x" else 1
        return max(0.0, (limits[i] - values[i]) / safety.shear_stiffness_N_per_mm - speed * lag)

    def _bounded(
        self, finals: dict[str, float], speeds: dict[str, float], here: dict[str, float], wrench, pressed: bool
    ) -> dict[str, float]:
        """The targets to send: the ends, or the same fraction of the way to each end at which the
        first axis reaches its bound (a path stays the path)."""
        fraction = 1.0
        for name, end in finals.items():
            left = end - here[name]
            if abs(left) <= TOLERANCE_MM:
                continue
            if name == "z":
                if left > 0:
                    continue  # lifting: the load can only fall
                top = min(here[name], self.approach_top())
                lowest = top - self._reach("z", here[name], speeds[name], wrench, pressed)
                allowed = max(0.0, here[name] - lowest)
            else:
                allowed = self._reach(name, here[name], speeds[name], wrench, pressed)
            fraction = min(fraction, allowed / abs(left))
        if fraction >= 1.0:
            return dict(finals)
        return {name: here[name] + fraction * (end - here[name]) for name, end in finals.items()}

    # -- sending ---------------------------------------------------------------------------------
    def _pressed_at(self, z_mm: float | None) -> bool:
        contact = self._contact
        if contact is None:
            return False
        return contact.loaded or (z_mm is not None and contact.below_surface(z_mm))

    def _send(self, finals: dict[str, float], speeds: dict[str, float], wrench, here: dict[str, float] | None = None):
        """Command ``finals`` (the moves' ends) as bounded targets; z's controller holds the floor
        before any descent leaves the host."""
        rig = self.rig
        here = dict(here or {})
        for name in finals:
            if name not in here:
                here[name] = rig.axes[name].position()
        pressed = self._pressed_at(here.get("z", rig.axes["z"].position() if "z" in rig.axes else None))
        issued = self._bounded(finals, speeds, here, wrench, pressed)
        if "z" in finals and finals["z"] < here["z"] - TOLERANCE_MM and self._floor is not None:
            self._floor.hold(self.controller_floor())
        for group in self._groups:
            group.difference_update(finals)  # an axis commanded anew leaves the move it was in
        self._groups = [group for group in self._groups if group] + [set(finals)]
        for name, target in issued.items():
            self._moving.add(name)
            self._commanded[name] = (finals[name], speeds[name])
            self._issued[name] = target
            self._moved = True
            rig.axes[name].move_to(target, speeds[name])

    def _short(self, name: str) -> bool:
        """Whether ``name``'s last target stops short of its move's end."""
        return name in self._issued and abs(self._issued[name] - self._commanded[name][0]) > self.rig.tolerance(name)

    def _rebound(self, positions: dict[str, float], idle: set[str], wrench) -> None:
        """Each check, for each move under way: re-issue it further on (less than EXTEND_FRACTION of
        its reach left, or at rest short of its end), or nearer (the load grew faster than assumed).
        ForceLimitExceeded when an axis rests short of its end with no reach left."""
        self._groups = [{n for n in group if n in self._commanded} for group in self._groups]
        self._groups = [group for group in self._groups if group]
        for group in self._groups:
            if any(self._short(n) for n in group) and group <= positions.keys():
                self._rebound_move(sorted(group), positions, idle, wrench)

    def _rebound_move(self, names: list[str], positions: dict[str, float], idle: set[str], wrench) -> None:
        short = {n for n in names if self._short(n)}
        finals = {n: self._commanded[n][0] for n in names}
        speeds = {n: self._commanded[n][1] for n in names}
        if self._floor is not None and "z" in finals and finals["z"] < positions["z"] - TOLERANCE_MM:
            self._floor.hold(self.controller_floor())  # a first contact may have raised the floor
        z_now = positions.get("z", getattr(self, "_last_z_mm", None))
        new = self._bounded(finals, speeds, positions, wrench, self._pressed_at(z_now))
        resend = False
        for n in names:
            step = self.rig.tolerance(n)  # the device's resolution: a nearer target is where it is
            reach_old = abs(self._issued[n] - positions[n])
            reach_new = abs(new[n] - positions[n])
            if reach_new < reach_old - max(step, 0.05 * reach_old):
                resend = True  # nearer: the bound shrank
            elif n in idle and n in short:
                resend = resend or reach_new > step  # at rest short of its end: on, if it may
            elif abs(new[n] - self._issued[n]) > step and reach_old < EXTEND_FRACTION * reach_new:
                resend = True
        if not resend:
            stuck = short & idle
            if stuck and all(abs(new[n] - positions[n]) <= self.rig.tolerance(n) for n in stuck):
                name = sorted(stuck)[0]
                self._held_at_limit(name, positions[name], wrench)
            return
        for n in names:
            self._issued[n] = new[n]
            self.rig.axes[n].move_to(new[n], speeds[n])

    def _held_at_limit(self, name: str, position: float, wrench) -> None:
        i = {"x": 0, "y": 1, "z": 2, "theta": 5}[name]
        unit = "N·mm" if name == "theta" else "N"
        value = float(wrench.as_array()[i]) if wrench is not None else float("nan")
        limit = float(self.rig.guard.limits[i])
        component = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")[i]
        raise ForceLimitExceeded(
            component,
            value,
            limit,
            unit,
            f"{name} stopped at {position:.4f}: {component} = {value:.3f} {unit} leaves no room under its limit "
            f"±{limit:.3f} {unit} for a further command at the contact's stiffness; all axes stopped",
        )
