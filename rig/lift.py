"""After a failure: z off the gel whenever it may be pressed (docs/safety.md, "After an interruption").

The motion session's stop sequence (rig/motion.py) calls ``_lift_clear`` once every axis has
stopped and come to rest. Pressed means: the averaged reading is loaded against the unloaded
reference, or z is below the remembered gel surface, or (with no gauge to tell) below the highest
z known to be free of load (rig/contact_state.py). With a gauge that answers, z goes up under
the guard to that clear height, then on until the averaged reading is unloaded, plus
CLEARANCE_MM; if that guarded lift itself stops, or there is no gauge, z is withdrawn open-loop
and slowly (``_withdraw_open_loop``, in the session: the one module that moves axes). What was
done is kept in the session's report and said on stderr.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

from rig.contact_state import CLEARANCE_MM, CONTACT_N, ContactTracker
from rig.errors import DeviceError, DeviceTimeout, ForceLimitExceeded, RigError, SafetyError

log = logging.getLogger("rig.motion")

LIFT_MAX_MM = 5.0  # how far an error lift searches for release: beyond any gel the rig takes (3 mm)
STEADY_MM = 0.2  # a reading unchanged over this much rise, above the surface, is the gauge's offset
MIN_POLLS_BEFORE_TIMEOUT = 50  # as the session's waits: a fast simulated clock may pass a deadline in a poll
TOLERANCE_MM = 1e-4


class SteadyLoad:
    """Whether the averaged reading has stopped changing while z rose STEADY_MM: the load is gone
    and what is left is the gauge's offset (a lift judged against a reference read while pressed)."""

    def __init__(self, contact: ContactTracker):
        self.contact = contact
        self.seen: list[tuple[float, float]] = []  # (z, averaged raw Fz)

    def unchanged(self, z_mm: float, wrench) -> bool:
        fz = self.contact.averaged_raw_fz(wrench)
        self.seen.append((z_mm, fz))
        below = [f for z, f in self.seen if z <= z_mm - STEADY_MM]
        if not below:
            return False
        del self.seen[: max(0, len(self.seen) - 200)]
        return (
            abs(below[-1] - fz) < CONTACT_N / 2
            and self.contact.surface_z() is not None
            and (
                z_mm > self.contact.surface_z() + TOLERANCE_MM  # type: ignore[operator]
            )
        )


class LiftAfterFailure:
    """The lift of a motion session (its stop sequence), mixed into ``rig.motion.Motion``."""

    # what the session provides
    rig: Any
    what: str
    retract_to_z: float | None
    surface_hint: tuple[float, str] | None
    _contact: ContactTracker | None
    _actions: list[str]
    _idle_since: float | None

    if TYPE_CHECKING:

        def move(self, targets: dict[str, float], speed: Any = None, *, timeout_s: float | None = None) -> Any: ...
        def _start(self, targets: dict[str, float], speeds: dict[str, float], poll_s: float | None = None) -> Any: ...
        def monitor(self, names: Any, guard: Any = None, what: str | None = None) -> set[str]: ...
        def _wait_at_rest(self) -> None: ...
        def _withdraw_open_loop(self, target: float, here: float, why: str) -> None: ...

    # -- after a failure: z off the gel ---------------------------------------------------
    def _act(self, text: str) -> None:
        """Something the stop sequence did: kept in the report and said on stderr."""
        self._actions.append(text)
        log.warning("%s", text)

    def _gauge_failed(self, failure: BaseException) -> bool:
        """The failure is the gauge's own: its device error, or a reading that is not a number."""
        gauge = self.rig.gauge
        if gauge is None or (isinstance(failure, ForceLimitExceeded) and failure.component == "wrench"):
            return True
        return isinstance(failure, DeviceError) and failure.device == getattr(gauge, "label", None)

    def _settled_reading(self):
        """A reading waited for past the stop; the tracker averages it with the samples before it."""
        self.rig.gauge.read_fresh()
        self.rig.gauge.read_fresh()  # one more arrival, so the average reaches past the stop
        return self.rig.gauge.read()

    def _lift_clear(self, failure: BaseException) -> None:
        """After an error: z off the gel whenever it may be pressed, and up to ``retract_to_z``.

        Pressed: the averaged reading is loaded against the unloaded reference, or z is below
        the remembered gel surface, or (with no gauge to tell) below the highest z known to be
        free of load. With a gauge that answers, z goes up to that clear height under a guard
        relaxed to the present load, then on until the averaged reading is unloaded, plus
        CLEARANCE_MM. Without one it is withdrawn open-loop at WITHDRAW_SPEED to the clear
        height (or LIFT_MAX_MM up when none is known)."""
        z = self.rig.axes["z"]
        cfg = self.rig.config.axes["z"]
        contact = self._contact
        here = z.position()
        if contact is not None:
            clear = contact.clear_height()
        else:  # the session failed while opening: only what the rig remembers
            guard = self.rig.depth_guard(self.surface_hint)
            clear = guard.surface_z + CLEARANCE_MM if guard is not None else None
        if self.retract_to_z is not None:
            clear = self.retract_to_z if clear is None else max(clear, self.retract_to_z)
        gauge_ok = contact is not None and not self._gauge_failed(failure)
        wrench = None
        if gauge_ok:
            try:
                wrench = self._settled_reading()
            except RigError as exc:
                gauge_ok = False
                self._act(f"the gauge did not answer after {self.what} ({exc})")
        loaded = contact is not None and wrench is not None and contact.is_loaded(wrench)
        below_surface = contact is not None and contact.below_surface(here)
        below_clear = clear is not None and here < clear - TOLERANCE_MM
        pressed = loaded or below_surface or (not gauge_ok and below_clear)
        if not pressed and not (self.retract_to_z is not None and below_clear):
            return
        if not gauge_ok:
            if clear is None and contact is None:
                self._act(f"z left at {here:.3f} mm: no gauge, and no remembered gel surface to withdraw above")
                return
            if clear is not None:
                self._withdraw_open_loop(min(cfg.travel[1], clear), here, "the highest z known to be free of load")
            else:
                self._withdraw_open_loop(min(cfg.travel[1], here + LIFT_MAX_MM), here, "no free height is known")
            return
        why = "loaded" if loaded else "below the gel surface" if below_surface else "below the approach height"
        try:
            if clear is not None and below_clear:
                self.move({"z": min(cfg.travel[1], clear)}, cfg.jog_speed)
            self._lift_until_unloaded(here)
        except Exception as exc:  # the lift itself failed (a trip, the gauge): z still goes up, open-loop
            self.rig.stop_all()
            self._wait_at_rest()
            self._act(f"the guarded lift stopped ({exc})")
            now = z.position()
            target = clear if clear is not None and clear > now else now + LIFT_MAX_MM
            self._withdraw_open_loop(min(cfg.travel[1], target), now, "after the guarded lift stopped")
            return
        self._act(f"z lifted from {here:.3f} to {z.position():.3f} mm ({why} when {self.what} stopped)")

    def _lift_until_unloaded(self, start_z: float) -> None:
        """Lift z until the averaged reading is unloaded, then CLEARANCE_MM more (at most LIFT_MAX_MM)."""
        z = self.rig.axes["z"]
        cfg = self.rig.config.axes["z"]
        contact = self._contact
        assert contact is not None
        here = z.position()
        top = min(cfg.travel[1], max(here, start_z + LIFT_MAX_MM))
        if not contact.is_loaded(self._settled_reading()) or top <= here + TOLERANCE_MM:
            return
        guard = self._start({"z": top}, {"z": cfg.jog_speed}, self.rig.config.safety.poll_s)
        deadline = self.rig.clock.now() + 5.0 + 2.0 * (top - here) / cfg.jog_speed
        polls = 0
        steady = SteadyLoad(contact)
        while contact.is_loaded(wrench := self.rig.gauge.read()):
            if contact.reference.assumed and steady.unchanged(self.rig.axes["z"].position(), wrench):
                # The reference was read while pressed (no tare remembered): a reading that no longer
                # falls as z rises is the gauge's own offset, not a load.
                contact.rebase(wrench, "a lift's steady reading (no tare remembered)")
                break
            if not self.monitor(("z",), guard, "lift clear") and self._idle_since is None:
                raise SafetyError(f"z lifted to {top:.3f} mm and the gauge still reads a load; lift it by hand")
            polls += 1
            if self.rig.clock.now() > deadline and polls > MIN_POLLS_BEFORE_TIMEOUT:
                raise DeviceTimeout(z.label, "lift clear", None, "z did not lift clear in time")
            self.rig.clock.sleep(self.rig.config.safety.poll_s)
        self.rig.stop_all()
        released = z.position()
        self.move({"z": min(top, released + CLEARANCE_MM)}, cfg.jog_speed)
