"""Whose gel surface is remembered: the z controller's power-up and the indenter (docs/safety.md).

A remembered surface is a number measured under conditions that can change without the software
being told: the controller powered off and on (its position counted from a new zero), z homed
again, another indenter mounted. Each surface records them (rig/rig_state.py), and one that does
not match the rig as it is now is unknown: descents then run at the in-contact speed until they
see the gel.

A power cycle is told by a token: a random number this tool writes into the z controller's
volatile memory (a Zaber's user.vdata.0) the first time it opens it after a power-up. A
controller that reads 0 there, or another number than the one remembered, was powered off and on
since (or written by another config of this rig). A controller without such memory (the PR-mode
drives) has no token: power cycles are then told only by z being unreferenced, and by the age.
"""

from __future__ import annotations

import secrets

from rig.errors import DeviceError, SafetyError


def check_power_up(rig) -> str | None:
    """Read the z controller's token, write a new one after a power-up; a note when surfaces
    measured before it became unknown. Nothing for a rig without z or a controller without one."""
    z = rig.axes.get("z")
    if z is None or not hasattr(z, "power_token"):
        return None
    state = rig.state
    token = z.power_token()
    if token is None:
        state.note_power_token(None)
        return None
    if token != 0 and token == state.power_token:
        return None
    new = secrets.randbits(62) + 1
    try:
        z.set_power_token(new)
        back = z.power_token()
    except DeviceError as exc:
        raise SafetyError(f"{z.label}: could not leave its power-up token ({exc}); nothing was moved") from None
    if back != new:
        raise SafetyError(
            f"{z.label}: wrote power-up token {new} and read back {back}: the controller does not keep it; "
            "nothing was moved"
        )
    had = [name or "unnamed indenter" for name, s in state.surfaces.items() if s.power_token is not None]
    state.note_power_token(new)
    if token == 0 and had:
        return (
            f"the z controller was powered off and on since the gel surface was measured ({', '.join(had)}): "
            "forgotten; descents run at the in-contact speed until they see the gel (rig find-contact measures it)"
        )
    return None
