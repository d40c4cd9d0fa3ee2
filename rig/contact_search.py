"""Find where the indenter touches the gel: the contact point the protocols start from.

Two passes under the armed force limits: a fast descent stops at the first touch;
then z lifts and comes down again at a tenth of the speed, and the z where |Fz|
first reaches the threshold is the contact point (a few µm inside the gel: the
indentation that makes that force, plus the distance moved in one poll). z lifts
clear afterwards. +z is away from the gel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

from rig.errors import RigError


@dataclass(frozen=True)
class ContactFound:
    z_mm: float  # axis coordinate of the contact point
    fz_N: float  # the force that marked it
    resolution_mm: float  # distance z moves in one poll at the slow speed
    at: dict[str, float] = field(default_factory=dict)  # every open axis's position at the contact (z: z_mm)

    def origin(self) -> tuple[tuple[float, float, float, float], list[str]]:
        """The contact point as ``rig run-protocol --origin`` takes it, x, y, z (mm), θ (deg), and
        the axes it could not read (not open or not configured: 0 stands in for them)."""
        missing = [name for name in ("x", "y", "theta") if name not in self.at]
        values = (self.at.get("x", 0.0), self.at.get("y", 0.0), self.z_mm, self.at.get("theta", 0.0))
        return values, missing


def _descend_until_touch(m, z_floor: float, speed: float, threshold_N: float) -> tuple[float, float]:
    rig = m.rig
    guard = m.start_move({"z": z_floor}, speed)
    while True:
        fz = rig.gauge.read().fz_N
        if abs(fz) >= threshold_N:
            m.stop()
            return rig.axes["z"].position(), fz
        if not m.monitor(("z",), guard, "contact search"):
            raise RigError(
                f"no contact down to z = {z_floor:.3f} mm (|Fz| stayed below {threshold_N} N); "
                "start lower or allow more travel"
            )
        rig.clock.sleep(rig.config.safety.poll_s)


def find_contact(
    rig,
    *,
    threshold_N: float = 0.05,
    speed_mm_s: float = 0.5,
    max_travel_mm: float = 10.0,
    backoff_mm: float = 0.5,
    on_start: Callable[[str], None] | None = None,
) -> ContactFound:
    """Search downwards from the present z (which must be clear of the gel), in one motion
    session: any error or signal stops z and lifts it clear of the gel."""
    if not all(math.isfinite(v) and v > 0 for v in (threshold_N, speed_mm_s, max_travel_mm, backoff_mm)):
        raise RigError(
            f"threshold ({threshold_N} N), speed ({speed_mm_s} mm/s), travel ({max_travel_mm} mm) "
            f"and backoff ({backoff_mm} mm) must be finite and > 0"
        )
    with rig.motion("contact search", on_start=on_start, search=True) as m:
        z_start = rig.axes["z"].position()
        low = rig.config.axes["z"].travel[0]
        z_floor = max(low, z_start - max_travel_mm)
        rig.tare(20)  # clear of the gel: this is the unloaded reading
        # Measured anew: a shorter indenter touches below the old surface's depth floor. Until the
        # search's first contact the descent runs at the in-contact speed (docs/safety.md).
        rig.state.forget_surface()
        z_touch, _ = _descend_until_touch(m, z_floor, speed_mm_s, threshold_N)
        m.move({"z": min(z_touch + backoff_mm, z_start)}, speed_mm_s)
        slow = speed_mm_s / 10
        z_contact, fz = _descend_until_touch(m, max(low, z_touch - backoff_mm), slow, threshold_N)
        at = {name: axis.position() for name, axis in rig.axes.items()}
        at["z"] = z_contact
        rig.state.remember_surface(z_contact, "find-contact")
        m.move({"z": min(z_contact + backoff_mm, z_start)}, speed_mm_s)
    return ContactFound(z_contact, fz, slow * rig.config.safety.poll_s, at)
