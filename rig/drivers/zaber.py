"""Zaber stages over the ASCII protocol (linear or rotary, any of the rig's axes).

``ZaberChain`` owns one serial port and the devices daisy-chained on it; every
exchange carries a message id and a checksum so that a late or garbled reply is
never taken for the answer to another command. ``ZaberAxis`` is one axis of one
device, in mm (or deg), converting native microsteps in one place.
"""

from __future__ import annotations

import itertools
import math

from rig.drivers import zaber_ascii as za
from rig.errors import DeviceRejected, DeviceTimeout, FramingError
from rig.transport.serial_link import SerialLink
from rig.types import AxisStatus, MotionState

# A device-scope volatile setting (FW 7.23 and later) that holds the rig's power-up token: 0 after
# the controller powers up (docs/hardware.md, "Zaber"; ASSUMED volatile, as Zaber's examples use it).
POWER_TOKEN_SETTING = "user.vdata.0"


class ZaberChain:
    def __init__(self, link: SerialLink, *, retries: int = 2, use_checksum: bool = True):
        self.link = link
        self.retries = retries
        self.use_checksum = use_checksum
        self._ids = itertools.cycle(range(100))
        self.recovered = 0  # exchanges that needed a retry (timeouts, garbled replies)

    def command(self, device: int, axis: int, text: str, *, name: str) -> za.Reply:
        """Send ``text`` and return the matching reply.

        Every command the drivers send is idempotent (absolute moves, reads, stop,
        home), so a timeout or garbled reply is retried ``retries`` times before the
        typed error is raised. A rejection is raised at once.
        """
        last: Exception | None = None
        with self.link.lock:
            for attempt in range(self.retries + 1):
                msg_id = next(self._ids)
                frame = za.format_command(device, axis, text, msg_id, self.use_checksum)
                self.link.discard_input()
                self.link.write(frame, frame.decode().strip())
                try:
                    reply = self._read_reply(device, axis, msg_id, frame, name)
                except (DeviceTimeout, FramingError) as exc:
                    last = exc
                    continue
                if attempt:
                    self.recovered += 1
                if reply.flag == "RJ":
                    reason = reply.data if reply.data in za.REJECTION_REASONS else f"unknown ({reply.data})"
                    raise DeviceRejected(
                        name, frame.decode().strip(), reply.raw.decode(errors="replace").strip(), reason
                    )
                return reply
        assert last is not None
        raise last

    def _read_reply(self, device: int, axis: int, msg_id: int, frame: bytes, name: str) -> za.Reply:
        command = frame.decode().strip()
        # Skip alerts (!), info lines (#) and stale replies to earlier message ids.
        for _ in range(16):
            line = self.link.read_until(b"\n", command)
            if not line.startswith(b"@"):
                continue
            try:
                reply = za.parse_reply(line)
            except za.ReplyParseError as exc:
                raise FramingError(name, command, line, str(exc)) from exc
            if reply.device == device and reply.message_id == msg_id and reply.axis in (axis, 0):
                return reply
        raise FramingError(name, command, None, "no reply matched the message id")

    def close(self) -> None:
        self.link.close()


class ZaberAxis:
    """One Zaber axis. ``position = native * scale + offset`` (scale may be negative)."""

    def __init__(
        self,
        chain: ZaberChain,
        *,
        name: str,
        device: int,
        axis: int = 1,
        scale: float,
        offset: float = 0.0,
        unit: str = "mm",
    ):
        if scale == 0:
            raise ValueError(f"axis {name}: scale must be non-zero")
        self.chain = chain
        self.name = name
        self.device = device
        self.axis = axis
        self.scale = scale
        self.offset = offset
        self.unit = unit
        self._speed_native: int | None = None
        self.label = f"{name} (Zaber device {device} axis {axis} on {chain.link.url})"

    # native units, in one place
    def to_native(self, position: float) -> int:
        return round((position - self.offset) / self.scale)

    def to_position(self, native: int) -> float:
        return native * self.scale + self.offset

    def speed_to_native(self, speed: float) -> int:
        return max(1, round(abs(speed / self.scale) * za.VELOCITY_UNITS_PER_USTEP_S))

    def _cmd(self, text: str) -> za.Reply:
        return self.chain.command(self.device, self.axis, text, name=self.label)

    def position(self) -> float:
        reply = self._cmd("get pos")
        try:
            return self.to_position(int(reply.data))
        except ValueError as exc:
            raise FramingError(self.label, "get pos", reply.raw, "position is not an integer") from exc

    def status(self) -> AxisStatus:
        reply = self._cmd("get pos")
        flags: tuple[str, ...] = ()
        if reply.warning != "--":
            flags = tuple(self._cmd("warnings").data.split()[1:])
        return AxisStatus(
            position=self.to_position(int(reply.data)),
            state=MotionState.BUSY if reply.busy else MotionState.IDLE,
            homed=not any(f in za.NOT_REFERENCED for f in flags),
            warnings=flags,
        )

    def faults(self, status: AxisStatus) -> list[str]:
        return [f"{f} ({za.FAULT_FLAGS[f]})" for f in status.warnings if f in za.FAULT_FLAGS]

    def move_to(self, target: float, speed: float) -> None:
        native_speed = self.speed_to_native(speed)
        if native_speed != self._speed_native:
            self._cmd(f"set maxspeed {native_speed}")
            self._speed_native = native_speed
        self._cmd(f"move abs {self.to_native(target)}")

    def stop(self) -> None:
        self._cmd("stop")

    def home(self) -> None:
        self._cmd("home")

    def clear_warnings(self) -> None:
        self._cmd("warnings clear")

    # -- the controller's own travel limits and a power-up token (rig/device_floor.py) ----------
    def _get_int(self, setting: str) -> int:
        reply = self._cmd(f"get {setting}")
        try:
            return int(reply.data)
        except ValueError as exc:
            raise FramingError(self.label, f"get {setting}", reply.raw, f"{setting} is not an integer") from exc

    def native_limits(self) -> tuple[int, int]:
        """The controller's limit.min and limit.max (microsteps)."""
        return self._get_int("limit.min"), self._get_int("limit.max")

    def set_native_limits(self, low: int, high: int) -> None:
        """Set limit.min and limit.max (microsteps); the caller reads them back."""
        self._cmd(f"set limit.min {int(low)}")
        self._cmd(f"set limit.max {int(high)}")

    def native_range(self, low: float, high: float) -> tuple[int, int]:
        """The microstep limits that keep the axis inside [low, high] (axis units), rounded inward."""
        a, b = sorted(((low - self.offset) / self.scale, (high - self.offset) / self.scale))
        return math.ceil(a - 1e-9), math.floor(b + 1e-9)

    def power_token(self) -> int | None:
        """The token the rig left in the controller's volatile user.vdata.0 (0 after a power-up);
        None where the firmware has no such setting (before 7.23)."""
        try:
            return int(self.chain.command(self.device, 0, f"get {POWER_TOKEN_SETTING}", name=self.label).data)
        except (DeviceRejected, ValueError):
            return None

    def set_power_token(self, token: int) -> None:
        self.chain.command(self.device, 0, f"set {POWER_TOKEN_SETTING} {int(token)}", name=self.label)

    def close(self) -> None:
        pass  # the chain owns the port
