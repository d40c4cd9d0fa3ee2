"""Planning a move inside the speed envelope and the depth guard (docs/safety.md): which speed
each part of a move may have, before anything moves.

A z descent passes up to three zones: clear of the gel (above a known surface + CLEARANCE_MM,
any speed), in the gel (the in-contact cap), below the depth floor (only with ``allow_deep``,
at the window's cap). A z-only move is split at the zone edges; any other move runs whole at
the cap of the deepest zone it enters. Sideways and twisting axes take the pressed caps while
the indenter is pressed or goes into the gel with them. A speed above a cap is clamped with a
note, or refused where clamping is not allowed; a cap no speed can meet is refused.
"""

from __future__ import annotations

import math
from typing import Callable

from rig.contact_state import CLEARANCE_MM
from rig.envelope import MIN_SPEED, Cap
from rig.errors import DepthLimitError, SpeedRefused

TOLERANCE_MM = 1e-4


class MovePlanner:
    """The planning of one session: its rig, its surface hint (a protocol's origin), whether it
    may go below the floor (``allow_deep``) or only searches (``search``: a target below the floor
    is brought up to it), and where its notes go."""

    def __init__(self, rig, surface_hint, allow_deep: bool, search: bool, note: Callable[[str], None]):
        self.rig = rig
        self.surface_hint = surface_hint
        self.allow_deep = allow_deep
        self.search = search
        self.note = note

    def check_depth(self, z_target: float) -> None:
        """DepthLimitError for a z target below the floor (unless ``allow_deep``); moves nothing."""
        guard = self.rig.depth_guard(self.surface_hint)
        if guard is not None and z_target < guard.floor_z - TOLERANCE_MM and not self.allow_deep:
            raise DepthLimitError(
                f"z target {z_target:.3f} mm is {guard.surface_z - z_target:.2f} mm below the gel surface: "
                f"{guard.describe()}; nothing was moved (--allow-deep goes deeper, slowly)"
            )

    def capped(self, cap: Cap, requested: float, clamp: bool) -> float:
        """``requested`` if the cap allows it; else clamped to the cap with a note, or refused."""
        slowest = getattr(self.rig.axes[cap.axis], "min_speed", 0.0)  # a drive's speed resolution
        if cap.speed < max(MIN_SPEED, slowest):
            raise SpeedRefused(
                f"axis {cap.axis}: no speed is safe {cap.why()} (the envelope allows {cap.speed:.2g} {cap.unit}/s); "
                "nothing was moved"
            )
        if requested <= cap.speed * (1 + 1e-9):
            return requested
        if not clamp:
            raise SpeedRefused(
                f"axis {cap.axis}: {requested:g} {cap.unit}/s is faster than the envelope's "
                f"{cap.speed:.3g} {cap.unit}/s {cap.why()}; nothing was moved"
            )
        step = 10.0 ** (math.floor(math.log10(cap.speed)) - 2)  # three significant digits, rounded down
        speed = max(MIN_SPEED, math.floor(cap.speed / step * (1 + 1e-12)) * step)
        self.note(f"{cap.axis}: {requested:g} {cap.unit}/s clamped to {speed:g} {cap.unit}/s {cap.why()}")
        return speed

    def plan(
        self,
        targets: dict[str, float],
        speeds: dict[str, float],
        poll_s: float,
        *,
        clamp: bool,
        split: bool,
        pressed: bool,
    ) -> list[tuple[dict[str, float], dict[str, float]]]:
        """The move as segments, each at a speed the guard can stop in time for the contact
        it may press. A z-only descent is split where it enters the gel (a known surface +
        CLEARANCE_MM) and the depth floor; anything else is one segment at the slowest cap
        of the zones it enters."""
        envelope = self.rig.envelope()
        out = dict(speeds)
        guard = self.rig.depth_guard(self.surface_hint)
        # full speed only above where the gel could be: the surface, its uncertainty and the clearance
        uncertainty = self.rig.config.safety.surface_uncertainty_mm
        entry = guard.surface_z + uncertainty + CLEARANCE_MM if guard is not None and not pressed else math.inf
        contact_zone = "gel" if guard is not None else "unknown"
        here = self.rig.axes["z"].position() if "z" in self.rig.axes else math.inf
        z_target = targets.get("z", here)
        descending = z_target < here - TOLERANCE_MM
        # sideways and twisting axes at the pressed caps while pressed, or when z goes into the gel with them
        pressed_during = pressed or (descending and z_target < entry)
        for name in targets:
            if name != "z" and pressed_during:
                out[name] = self.capped(envelope.cap(name, "pressed", poll_s), out[name], clamp)
        if "z" not in targets or not descending:
            return [(targets, out)]  # lifting, or z not moving: the normal load can only fall
        if self.search and guard is not None and z_target < guard.floor_z:
            z_target = guard.floor_z  # a search looks no deeper than the floor
            targets = dict(targets, z=z_target)
            self.note(f"z: searching no deeper than the depth floor, z = {z_target:.3f} mm")
        self.check_depth(z_target)
        v = out["z"]
        floor = guard.floor_z if guard is not None else -math.inf
        # (top, bottom, the zone whose cap applies)
        bands = [(math.inf, entry, None), (entry, floor, contact_zone), (floor, -math.inf, "deep")]
        entered = [
            (bottom, zone)
            for top, bottom, zone in bands
            if here > bottom + TOLERANCE_MM and z_target < top - TOLERANCE_MM
        ]
        if not entered:  # within a hair of a zone's edge: at the slower of the two
            entered = [(floor, contact_zone)]

        def speed_in(zone: str | None) -> float:
            return v if zone is None else self.capped(envelope.cap("z", zone, poll_s), v, clamp)

        if not split or len(targets) > 1:
            out["z"] = speed_in(entered[-1][1])  # the whole move at the speed of the deepest zone it enters
            return [(targets, out)]
        segments: list[tuple[dict[str, float], dict[str, float]]] = []
        for low, zone in entered:
            end, speed = max(low, z_target), speed_in(zone)
            if segments and segments[-1][1]["z"] == speed:
                segments[-1] = ({"z": end}, {"z": speed})
            else:
                segments.append(({"z": end}, {"z": speed}))
        return segments or [(targets, out)]
