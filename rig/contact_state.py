"""Is the indenter pressing on the gel? A motion session's record of where the load is.

One poll of one sample is not enough to decide that (a session that starts pressed has no
unloaded reading; gauge noise is a few hundredths of a newton). The tracker combines:

- an **unloaded reference** (raw Fz with nothing touching): this session's first reading when
  z is known to be clear of the gel surface, else the rig's remembered tare
  (rig/rig_state.py, from `rig zero`, a protocol's tare or find-contact in any process),
  else this session's first reading, marked as assumed;
- **averaged readings**: the mean of the newest gauge samples, not one;
- the **gel surface** (remembered, or a protocol's origin as a hint) and the **last z seen
  load-free** in this session, so that z can be withdrawn to a known free height even when
  the gauge is gone.

The first contact a session sees while z goes down becomes the rig's remembered gel surface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.config import surface_tolerance_mm
from rig.errors import ForceLimitExceeded, SafetyError

CONTACT_N = 0.05  # |ΔFz| of the averaged reading that means touching: find-contact's default threshold
FREE_DESCENT_MM = 0.1  # unloaded descent that shows a session started in the air (≥ 0.1 N/mm × this > noise)
AVERAGE_SAMPLES = 5  # newest gauge samples averaged for a contact decision
CLEARANCE_MM = 0.5  # lifted this far above the surface, or past where the load went away


class StartedPressed(SafetyError):
    """A session with nothing remembered met a load at once: it may have started pressed."""


@dataclass(frozen=True)
class Reference:
    fz_raw_N: float  # the raw (untared) Fz with nothing touching
    source: str  # where it came from, for messages
    assumed: bool  # nothing confirmed that the indenter was clear when it was taken


class ContactTracker:
    """``entry``: the session's first (fresh) reading; ``z_mm``: z then (None without a z axis)."""

    def __init__(self, rig, entry, z_mm: float | None, surface_hint: tuple[float, str] | None = None):
        self.rig = rig
        self.surface_hint = surface_hint
        self.free_z: float | None = None  # the last z where the averaged load was below CONTACT_N
        guard = rig.depth_guard(surface_hint)
        tare = rig.state.tare
        entry_fz = self.averaged_raw_fz(entry)
        self._entry_raw = entry.as_array() + np.asarray(getattr(rig.gauge, "bias", np.zeros(6)))
        if guard is not None and z_mm is not None and z_mm > guard.surface_z + CLEARANCE_MM:
            self.reference = Reference(entry_fz, "this session's start, z clear of the gel", False)
            self.free_z = z_mm
            self._remember_unloaded()
        elif tare is not None:
            self.reference = Reference(tare.fz_N, "the remembered tare", False)
        else:
            self.reference = Reference(entry_fz, "this session's start (assumed unloaded)", True)
        self.start_z = z_mm
        self.loaded = self.is_loaded(entry) or (z_mm is not None and self.below_surface(z_mm))

    # -- readings ----------------------------------------------------------------------------
    def raw_fz(self, wrench) -> float:
        return float(wrench.fz_N + np.asarray(getattr(self.rig.gauge, "bias", np.zeros(6)))[2])

    def averaged_raw_fz(self, wrench) -> float:
        """The mean raw Fz of the newest samples (the wrench itself for a polled gauge)."""
        buffer = getattr(self.rig.gauge, "buffer", None)
        if buffer is None or not getattr(self.rig.gauge, "streaming", False):
            return self.raw_fz(wrench)
        samples = buffer.newest(AVERAGE_SAMPLES)
        if not samples:
            return self.raw_fz(wrench)
        return float(np.mean([s.fz_N for s in samples]))

    def is_loaded(self, wrench) -> bool:
        """Over a limit, or the averaged Fz away from the unloaded reference by CONTACT_N."""
        try:
            self.rig.guard.check(wrench)
        except ForceLimitExceeded:
            return True
        return abs(self.averaged_raw_fz(wrench) - self.reference.fz_raw_N) >= CONTACT_N

    # -- where the gel is ---------------------------------------------------------------------
    def surface_z(self) -> float | None:
        guard = self.rig.depth_guard(self.surface_hint)
        return None if guard is None else guard.surface_z

    def below_surface(self, z_mm: float) -> bool:
        surface = self.surface_z()
        return surface is not None and z_mm < surface

    def observe(self, wrench, z_mm: float | None, descending: bool, what: str) -> bool:
        """One poll's reading at ``z_mm``. Returns True when it is a first contact: unloaded
        before, loaded now, z going down; that z becomes the rig's remembered gel surface.

        With an assumed reference (nothing remembered: the session may have started pressed) a
        first contact counts only after FREE_DESCENT_MM of unloaded descent, which no pressed
        start can show (its load grows as soon as z goes down); that confirms the reference.
        One sooner raises StartedPressed: the rig cannot tell where the gel is."""
        loaded = self.is_loaded(wrench)
        # Counted in every phase of a move: going down, braking at the end of a segment, or at rest
        # after one (z no higher than where it last read no load). Not below a known surface with a
        # reference read there: the session started pressed, and more load is no first contact.
        came_down = z_mm is not None and self.free_z is not None and z_mm <= self.free_z + 1e-4
        in_gel = self.reference.assumed and z_mm is not None and self.below_surface(z_mm)
        first = loaded and not self.loaded and (descending or came_down) and z_mm is not None and not in_gel
        if not loaded and z_mm is not None:
            self.free_z = z_mm
        if first:
            assert z_mm is not None
            if self.reference.assumed:
                if self.start_z is None or self.start_z - z_mm < FREE_DESCENT_MM:
                    raise StartedPressed(
                        f"z met a load {max(0.0, (self.start_z or z_mm) - z_mm):.3f} mm below where this session "
                        "started, and the rig remembers no unloaded reading or gel surface: it may have started "
                        "pressed. Lift z clear of the gel, then `rig zero` (or `rig find-contact`)"
                    )
                self.reference = Reference(self.reference.fz_raw_N, "this session's start (confirmed unloaded)", False)
                self._remember_unloaded()
            first = self._remember_surface(z_mm, what)
        self.loaded = loaded
        return first

    def _remember_unloaded(self) -> None:
        """A rig that has no tare remembered keeps this session's start, now known to be unloaded,
        as its unloaded reading: a later session that starts pressed judges contact by it instead of
        mistaking the gauge's constant offset for a load (docs/safety.md, "No tare")."""
        if self.rig.state.tare is None and np.all(np.isfinite(self._entry_raw)):
            self.rig.state.remember_tare(self._entry_raw)

    def rebase(self, wrench, why: str) -> None:
        """Take the averaged reading now as the unloaded reference (a lift found the load gone)."""
        self.reference = Reference(self.averaged_raw_fz(wrench), why, False)
        self.loaded = False

    def _remember_surface(self, z_mm: float, what: str) -> bool:
        """A first contact at ``z_mm`` becomes the remembered surface when none is remembered, when
        it lies above the remembered one (contact is only ever seen late: the surface is higher
        than thought), or more than surface_tolerance_mm below it (a new indenter, a moved sensor).
        A little below, the remembered one stays: find-contact's slow second pass measures it more
        closely than a contact seen at speed, which the averaged reading sees late."""
        remembered = self.rig.state.surface
        thickness = self.rig.config.safety.gel_thickness_mm or 0.0
        if remembered is not None and remembered.z_mm - surface_tolerance_mm(thickness) <= z_mm <= remembered.z_mm:
            return False  # a contact seen late, just below it: the remembered surface stands (never one above)
        self.rig.state.remember_surface(z_mm, f"first contact ({what})")
        return True

    def clear_height(self) -> float | None:
        """The highest z known to be free of load: above the gel surface, or where this session
        last saw no load. None when neither is known."""
        trusted = not self.reference.assumed  # against an assumed reference "unloaded" may be the start's load
        candidates = [z for z in (self.free_z,) if z is not None and trusted]
        surface = self.surface_z()
        if surface is not None:
            candidates.append(surface + CLEARANCE_MM)
        candidates = [z for z in candidates if math.isfinite(z)]
        return max(candidates) if candidates else None
