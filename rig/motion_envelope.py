"""The speed envelope and the depth guard as a motion session applies them while it moves
(docs/safety.md, "Depth guard and speed envelope"): a move planned in zones before it starts
(rig/move_plan.py), a z descent slowed when it meets a contact its speed was not planned for and
stopped at the depth floor, and the load predicted at the end of a stop (rig/load_watch.py).
Mixed into ``rig.motion.Motion``; commands go out through its ``_send`` (rig/bounded.py).
"""

from __future__ import annotations

from typing import Any, Callable

from rig.contact_state import ContactTracker
from rig.envelope import MIN_SPEED
from rig.errors import DepthLimitError, SpeedRefused
from rig.load_watch import check_load_ahead
from rig.move_plan import TOLERANCE_MM, MovePlanner
from rig.types import WrenchGuard

STIFFNESS_SPAN_MM = 0.005  # z travel behind one dFz/dz estimate (averaged readings: gauge noise / span ≪ k)
STIFFNESS_POLLS = 6  # polls kept for it


class EnvelopeWatch:
    """The envelope half of a motion session."""

    rig: Any
    surface_hint: tuple[float, str] | None
    allow_deep: bool
    search: bool
    _contact: ContactTracker | None
    _commanded: dict[str, tuple[float, float]]
    _moving: set[str]
    _pressing: list[tuple[float, float]]
    _poll_s: float
    _strict: bool
    _slowed_s: float
    _previous: Any
    _last_z_mm: float
    _move_started_s: float
    _note: Callable[[str], None]
    _send: Callable[..., None]

    # -- the envelope: depth and speed ------------------------------------------------------
    def _pressed_now(self) -> bool:
        contact = self._contact
        if contact is None:
            return False
        if contact.loaded:
            return True
        return "z" in self.rig.axes and contact.below_surface(self.rig.axes["z"].position())

    def _plan(
        self, targets: dict[str, float], speeds: dict[str, float], poll_s: float, clamp: bool, split: bool = True
    ) -> list[tuple[dict[str, float], dict[str, float]]]:
        """The move as segments inside the speed envelope (rig/move_plan.py)."""
        planner = MovePlanner(self.rig, self.surface_hint, self.allow_deep, self.search, self._note)
        return planner.plan(targets, speeds, poll_s, clamp=clamp, split=split, pressed=self._pressed_now())

    def _govern(self, z_mm: float, wrench) -> None:
        """Mid-move: a z descent slows when it meets a contact its speed was not planned for
        (a first contact, a stiffer contact than assumed), and stops at the depth floor."""
        commanded = self._commanded.get("z")
        if commanded is None or "z" not in self._moving:
            return
        target, speed = commanded
        if target >= z_mm - TOLERANCE_MM:
            return  # lifting, or there
        envelope = self.rig.envelope()
        contact = self._contact
        assert contact is not None
        guard = self.rig.depth_guard(self.surface_hint)
        if guard is not None and not self.allow_deep:
            if self.search and z_mm >= guard.floor_z and target < guard.floor_z - TOLERANCE_MM:
                # the search looks no deeper than the floor (its caller stops at its own threshold)
                target = guard.floor_z
                self._send({"z": target}, {"z": speed}, wrench, {"z": z_mm})
                self._note(f"z: searching no deeper than the depth floor, z = {target:.3f} mm")
            if z_mm < guard.floor_z - TOLERANCE_MM or target < guard.floor_z - TOLERANCE_MM:
                self.rig.stop_all()
                raise DepthLimitError(
                    f"z stopped at {z_mm:.3f} mm on its way to {target:.3f} mm: {guard.describe()} "
                    "(--allow-deep goes deeper, slowly)"
                )
        if contact.loaded:
            self._pressing.append((z_mm, contact.averaged_raw_fz(wrench)))
            del self._pressing[:-STIFFNESS_POLLS]
            (z0, f0), (z1, f1) = self._pressing[0], self._pressing[-1]
            if z0 - z1 >= STIFFNESS_SPAN_MM and f1 > f0 and envelope.note_stiffness((f1 - f0) / (z0 - z1)):
                k, _ = envelope.normal_stiffness()
                self._note(f"z: the contact measures stiffer than assumed; assuming {k:.3g} N/mm")
        deep = guard is not None and z_mm < guard.floor_z + TOLERANCE_MM
        zone = "deep" if deep else "gel" if guard is not None else "unknown"
        if not contact.loaded and not deep and not contact.reference.assumed and guard is not None:
            return  # clear of the gel, on a planned approach
        cap = envelope.cap("z", zone, self._poll_s)
        if speed > cap.speed * (1 + 1e-9):
            if self._strict:
                self.rig.stop_all()
                raise SpeedRefused(
                    f"z stopped at {z_mm:.3f} mm: its {speed:g} mm/s is no longer inside the speed envelope "
                    f"({cap.speed:.3g} mm/s) {cap.why()}; this step may not be slowed: raise [safety] "
                    "stiffness_N_per_mm to this contact's and run it slower"
                )
            if cap.speed < MIN_SPEED:
                self.rig.stop_all()
                raise SpeedRefused(
                    f"z stopped at {z_mm:.3f} mm: no speed is safe {cap.why()} (the envelope allows "
                    f"{cap.speed:.2g} mm/s)"
                )
            slower = cap.speed
            self._slowed_s += 2.0 * (z_mm - target) / slower  # the wait's deadline moves with the slower speed
            self._send({"z": target}, {"z": slower}, wrench, {"z": z_mm})
            self._note(f"z: slowed from {speed:g} to {slower:.3g} mm/s {cap.why()}")

    def _check_predicted(self, wrench, guard: WrenchGuard) -> None:
        """The load predicted at the end of a stop, and a gauge gone quiet (rig/load_watch.py)."""
        previous, self._previous = self._previous, (wrench.t_s, wrench.as_array())
        z = self._commanded.get("z")
        if set(self._moving) == {"z"} and z is not None and z[0] > self._last_z_mm:
            return  # z going up, alone: the load can only fall
        speeds = {name: self._commanded[name][1] if name in self._commanded else 0.0 for name in self._moving}
        check_load_ahead(self.rig, wrench, guard, speeds, self._poll_s, self._move_started_s, previous)
