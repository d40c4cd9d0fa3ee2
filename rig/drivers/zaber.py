"""Zaber stages over the ASCII protocol (linear or rotary, any of the rig's axes).

``ZaberChain`` owns one serial port and the devices daisy-chained on it; every
exchange carries a message id and a checksum so that a late or garbled reply is
never taken for the answer to another command. ``ZaberAxis`` is one axis of one
device, in mm (or deg), converting native microsteps in one place.
"""

from __future__ import annotations

import itertools

from rig.drivers import zaber_ascii as za
from rig.errors import DeviceRejected, DeviceTimeout, FramingError
from rig.transport.serial_link import SerialLink
from rig.types import AxisStatus, MotionState


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

    def close(self) -> None:
        pass  # the chain owns the port
