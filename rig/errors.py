"""Typed errors of the rig layer.

Every device error names the device, the command that was sent and what came back,
so a message in a log is enough to know which cable to look at.
"""

from __future__ import annotations

from common.errors import ToolError


class RigError(ToolError):
    """Base class of what the rig layer (devices, motion, safety) raises on purpose."""


class DeviceError(RigError):
    """A device did something other than what was asked."""

    def __init__(self, device: str, command: str, reply: object, message: str):
        self.device = device
        self.command = command
        self.reply = reply
        super().__init__(f"{device}: {message} (command {command!r}, reply {reply!r})")


class DeviceTimeout(DeviceError):
    """No (complete) reply arrived within the timeout."""


class FramingError(DeviceError):
    """A reply arrived but was garbled: bad checksum/CRC, wrong length, unparsable."""


class DeviceRejected(DeviceError):
    """The device refused the command (Zaber RJ, Modbus exception response)."""

    def __init__(self, device: str, command: str, reply: object, reason: str):
        self.reason = reason
        super().__init__(device, command, reply, f"rejected: {reason}")


class DeviceFault(DeviceError):
    """The device reports a fault condition (stall, limit error, alarm, driver disabled)."""

    def __init__(self, device: str, command: str, reply: object, fault: str):
        self.fault = fault
        super().__init__(device, command, reply, f"fault: {fault}")


class DeviceDisconnected(DeviceError):
    """The port vanished or closed under us (unplugged cable, powered-off device)."""


class SafetyError(RigError):
    """A motion was refused or stopped to protect the hardware."""


class SoftLimitError(SafetyError):
    """A target lies outside an axis's configured travel; nothing was moved."""

    def __init__(self, axis: str, target: float, low: float, high: float, unit: str):
        self.axis, self.target, self.low, self.high = axis, target, low, high
        super().__init__(
            f"axis {axis}: target {target:.4f} {unit} is outside the soft limits "
            f"[{low:.4f}, {high:.4f}] {unit}; nothing was moved"
        )


class ForceLimitExceeded(SafetyError):
    """The gauge read a force or torque beyond the armed limit; motion was stopped."""

    def __init__(self, component: str, value: float, limit: float, unit: str, message: str | None = None):
        self.component, self.value, self.limit = component, value, limit
        super().__init__(
            message or f"{component} = {value:.3f} {unit} exceeds the limit ±{limit:.3f} {unit}; all axes stopped"
        )


class DepthLimitError(SafetyError):
    """A z target or position below the depth guard's floor (docs/safety.md, "Depth guard")."""


class SpeedRefused(SafetyError):
    """A speed the envelope cannot make safe, where clamping it is not allowed (a protocol's
    captured step: a slower step would no longer match its planned capture times)."""


class NotBuiltYet(RigError):
    """A capability that a later issue builds; says so instead of half-working."""


class DeviceBusy(RigError):
    """Another process holds a device this process was about to open (its claim in the
    runtime folder, or the port's own lock): nothing was opened (rig/ownership.py).

    ``pid``, ``command`` and ``since`` name the holder where it is known; the message is one
    line: ``device /dev/pts/7 (axes x, y, z) is held by pid 4242 (rig console --config
    rig-sim.toml) since 13:05:02; stop that process first``.
    """

    def __init__(
        self,
        device: str,
        roles: str = "",
        *,
        pid: int | None = None,
        command: str | None = None,
        since: str | None = None,
        detail: str = "",
        subject: str = "device",
    ):
        self.device, self.roles, self.detail = device, roles, detail
        self.pid, self.command, self.since = pid, command, since
        holder = "another process" if pid is None else f"pid {pid}"
        holder += (f" ({command})" if command else "") + (f" since {since}" if since else "")
        holder += f" {detail}" if detail else ""
        used_by = f" ({roles})" if roles else ""
        super().__init__(f"{subject} {device}{used_by} is held by {holder}; stop that process first")
