"""The depth floor in the z controller itself (docs/safety.md, "The floor in the controller").

The host's depth guard and force guard act only while the host runs. A process frozen
(SIGSTOP, a stalled machine) or killed mid-descent leaves the stage running to the last target
it was given. So before any z descent a session sets the z controller's own travel limit (a
Zaber's limit.min or limit.max, a PR-mode drive's software limit) to the depth floor, reads it
back, and restores the controller's own limits on every way out. The limits it found are written
into the rig state *before* it narrows them, so that a later command that opens z (the first
thing it does after a killed process) finds and restores them.

Only the floor's side is narrowed, and only ever narrower than what the controller had: a user's
own tighter limit stays.
"""

from __future__ import annotations

import logging
import os
import time

from rig.errors import DeviceError, SafetyError
from rig.rig_state import DeviceLimits, age_text

log = logging.getLogger("rig.motion")


def _controller(rig):
    z = rig.axes.get("z")
    if z is None or not all(hasattr(z, name) for name in ("native_limits", "set_native_limits", "native_range")):
        return None
    return z


def restore_left_behind(rig) -> str | None:
    """Restore z's controller limits that a killed or crashed session left narrowed; a note saying
    so. Called when a command opens z: its claim means no live process holds z any more."""
    record = rig.state.device_limits.get("z")
    z = _controller(rig)
    if record is None or z is None:
        return None
    z.set_native_limits(*record.saved)
    back = z.native_limits()
    if back != record.saved:
        raise SafetyError(
            f"{z.label}: restoring its travel limits {record.saved} (left narrowed to {record.narrowed} by pid "
            f"{record.pid}) read back {back}; set them by hand"
        )
    rig.state.remember_device_limits("z", None)
    return (
        f"z's controller travel limits, left narrowed to the depth floor by pid {record.pid} "
        f"{age_text(record.t_unix)} (that process stopped before it could restore them), are restored"
    )


class ControllerFloor:
    """z's controller limit held at a floor while a session descends; ``release`` restores it."""

    def __init__(self, rig):
        self.rig = rig
        self.floor_z: float | None = None  # the floor now in the controller
        self.saved: tuple[int, int] | None = None

    def hold(self, floor_z: float) -> None:
        """The controller refuses (or stops short of) any z below ``floor_z`` from now on, read
        back before this returns. SafetyError, and nothing moved, where it cannot."""
        if self.floor_z is not None and abs(self.floor_z - floor_z) < 1e-6:
            return
        z = _controller(self.rig)
        if z is None:
            axis = self.rig.axes.get("z")
            raise SafetyError(
                f"{getattr(axis, 'label', 'z')}: its controller cannot hold a travel limit, so a frozen or killed "
                "process could drive z through the gel; descents are refused (docs/safety.md)"
            )
        try:
            if self.saved is None:
                self.saved = z.native_limits()
            narrowed = self._narrowed(z, floor_z)
            self.rig.state.remember_device_limits("z", DeviceLimits(self.saved, narrowed, os.getpid(), time.time()))
            z.set_native_limits(*narrowed)
            back = z.native_limits()
        except DeviceError as exc:
            raise SafetyError(f"{z.label}: could not set its travel limit to the depth floor ({exc})") from None
        if back != narrowed:
            raise SafetyError(
                f"{z.label}: set its travel limits to {narrowed} (the depth floor z = {floor_z:.3f} mm) and read back "
                f"{back}: the controller does not keep them; nothing more is moved"
            )
        self.floor_z = floor_z

    def _narrowed(self, z, floor_z: float) -> tuple[int, int]:
        assert self.saved is not None
        low, high = self.saved
        top = self.rig.config.axes["z"].travel[1]
        floor_native = z.native_range(floor_z, max(top, floor_z))
        if z.scale > 0:  # deeper is fewer steps: the floor is limit.min
            return max(low, floor_native[0]), high
        return low, min(high, floor_native[1])  # deeper is more steps: the floor is limit.max

    def release(self) -> None:
        """The controller's own limits back, read back; the rig state forgets the record."""
        if self.saved is None:
            return
        z = _controller(self.rig)
        assert z is not None
        saved, self.saved, self.floor_z = self.saved, None, None
        z.set_native_limits(*saved)
        back = z.native_limits()
        if back != saved:
            raise SafetyError(f"{z.label}: restored its travel limits to {saved} and read back {back}")
        self.rig.state.remember_device_limits("z", None)
