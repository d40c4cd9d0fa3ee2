"""Setting a rig up at the gel (``rig zero``, ``rig find-contact``): a tare taken only clear of the gel,
and the contact point found and kept as the origin protocols start from.

Both work on an open ``Rig`` and print nothing: what they did comes back for the command to word.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from rig.contact_search import ContactFound, find_contact
from rig.contact_state import CLEARANCE_MM
from rig.errors import RigError
from rig.rig_state import Origin


class PressedTare(RigError):
    """A tare asked for while z is not clear of the remembered gel surface."""


def tare_clear_of_gel(rig, samples: int):
    """Tare the gauge over ``samples`` readings (``Rig.tare``, which remembers the bias for the rig);
    PressedTare, before any reading, while z is below the remembered gel surface plus the clearance:
    a tare then would count the indenter's load as zero."""
    guard = rig.depth_guard()
    if guard is not None and "z" in rig.axes:
        z = rig.axes["z"].position()
        if z < guard.surface_z + CLEARANCE_MM:
            raise PressedTare(
                f"z = {z:.3f} mm is not clear of the gel surface at z = {guard.surface_z:.3f} mm ({guard.how}): "
                "a tare now would count the indenter's load as zero; lift z above "
                f"{guard.surface_z + CLEARANCE_MM:.3f} mm first"
            )
    return rig.tare(samples)


@dataclass(frozen=True)
class ContactOrigin:
    """The contact found, as an origin (x, y, z, theta; ``missing``: the axes 0 stands in for), the
    origin remembered before it (now forgotten) and the one stored (None: not asked to), and where
    the rig's state is kept (None: this process only)."""

    found: ContactFound
    values: tuple[float, float, float, float]
    missing: list[str]
    forgotten: Origin | None
    stored: Origin | None
    where: Path | None


def find_origin(
    rig,
    *,
    threshold_N: float,
    speed_mm_s: float,
    max_travel_mm: float,
    set_origin: bool,
    on_start: Callable[[str], None] | None = None,
) -> ContactOrigin:
    """Find the gel (rig/contact_search.py: the surface is remembered for the mounted indenter), forget
    the origin remembered before (it predates this contact) and, with ``set_origin``, remember this one."""
    found = find_contact(
        rig, threshold_N=threshold_N, speed_mm_s=speed_mm_s, max_travel_mm=max_travel_mm, on_start=on_start
    )
    values, missing = found.origin()
    forgotten = rig.state.forget_origin()
    stored = rig.state.remember_origin(values) if set_origin else None
    return ContactOrigin(found, values, missing, forgotten, stored, rig.state.path)
