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

    def __init__(self, component: str, value: float, limit: float, unit: str):
        self.component, self.value, self.limit = component, value, limit
        super().__init__(f"{component} = {value:.3f} {unit} exceeds the limit ±{limit:.3f} {unit}; all axes stopped")


class NotBuiltYet(RigError):
    """A capability that a later issue builds; says so instead of half-working."""
