"""A Modbus RTU bus (RS-485 line or ``socket://`` RTU-over-TCP): request/reply exchanges.

Framed here (``modbus_frames``) rather than through pymodbus, so that every reply is
checked against its own request before a value is used, and the wait for it follows
the port's clock (``serial_link``). pymodbus 3.16 checks the CRC and the device id,
but takes any other sound frame as the answer (a late reply to the previous request
could become a position or an alarm), and waits in real time only.

Before each request stale input is discarded. A reply with a bad CRC, or none within
the timeout, is retried ``retries`` times; a sound frame answering another request
(device id, function, byte count, echoed register/value/quantity) is skipped and the
request's own reply awaited. Exception responses become ``DeviceRejected`` with the
Modbus exception name (not retried: the device answered); no valid reply after the
retries ``DeviceTimeout`` or ``FramingError``; a vanished port ``DeviceDisconnected``.
Every error names the device. A late reply to an *identical* request cannot be told
apart on RTU (no transaction id); it carries the same quantity, at most one timeout old.
"""

from __future__ import annotations

from rig.errors import DeviceRejected, DeviceTimeout, FramingError
from rig.transport import modbus_frames as mf
from rig.transport.serial_link import SerialLink

# Modbus application exception codes (Modbus Application Protocol v1.1b3, §7).
EXCEPTION_NAMES = {
    1: "ILLEGAL FUNCTION",
    2: "ILLEGAL DATA ADDRESS",
    3: "ILLEGAL DATA VALUE",
    4: "SERVER DEVICE FAILURE",
    5: "ACKNOWLEDGE",
    6: "SERVER DEVICE BUSY",
    8: "MEMORY PARITY ERROR",
    10: "GATEWAY PATH UNAVAILABLE",
    11: "GATEWAY TARGET DEVICE FAILED TO RESPOND",
}
# Other requests' replies skipped while awaiting one reply, before the try counts as
# failed: a bus holds at most a few late replies, a device spamming frames is broken.
MAX_OTHER_REPLIES = 4


def to_signed16(value: int) -> int:
    return value - 0x10000 if value & 0x8000 else value


def to_unsigned16(value: int) -> int:
    if not -0x8000 <= value <= 0xFFFF:
        raise ValueError(f"{value} does not fit a 16-bit register")
    return value & 0xFFFF


def split_int32(value: int) -> list[int]:
    """Signed 32-bit value as two registers, high word first."""
    if not -(2**31) <= value < 2**31:
        raise ValueError(f"{value} does not fit a signed 32-bit register pair")
    v = value & 0xFFFFFFFF
    return [v >> 16, v & 0xFFFF]


def join_int32(high: int, low: int) -> int:
    v = (high << 16) | low
    return v - 2**32 if v & 0x80000000 else v


class ModbusBus:
    """One Modbus RTU line; methods take the device id of the drive or gauge on it."""

    def __init__(self, url: str, *, baudrate: int, timeout_s: float, retries: int, device: str):
        self.url = url
        self.device = device
        self.retries = retries
        self.link = SerialLink(url, baudrate=baudrate, timeout_s=timeout_s, device=device)
        self.lock = self.link.lock
        self.stale_frames = 0  # other requests' replies seen and skipped
        self.failed_tries = 0  # tries that timed out or got a garbled reply

    def _exchange(self, request: bytes, what: str, device: str) -> list[int] | None:
        last: Exception | None = None
        for _ in range(self.retries + 1):
            with self.lock:
                self.link.discard_input(device=device)
                self.link.write(request, what, device=device)
                try:
                    return self._await_reply(request, what, device)
                except mf.ExceptionReply as exc:
                    name = EXCEPTION_NAMES.get(exc.code, f"exception {exc.code}")
                    raise DeviceRejected(
                        device, what, f"exception response, code {exc.code}", f"Modbus exception {exc.code} ({name})"
                    ) from None
                except (DeviceTimeout, FramingError) as exc:
                    self.failed_tries += 1
                    last = exc
        assert last is not None  # the loop ran at least once (retries >= 0) and every try failed
        raise last

    def _await_reply(self, request: bytes, what: str, device: str) -> list[int] | None:
        other = None
        for _ in range(MAX_OTHER_REPLIES + 1):
            try:
                frame = self.link.read_frame(mf.reply_length, what, device=device)
                return mf.parse_reply(request, frame)
            except mf.BadFrame as exc:
                raise FramingError(device, what, None, f"garbled Modbus reply on {self.url}: {exc}") from None
            except mf.OtherReply as exc:
                self.stale_frames += 1
                other = f"{exc} ({frame.hex(' ')})"
        raise FramingError(device, what, None, f"replies on {self.url} answer other requests: {other}")

    def read_holding(self, device_id: int, address: int, count: int, *, device: str) -> list[int]:
        what = f"read holding {address:#06x} x{count} @id {device_id}"
        request = mf.read_request(device_id, mf.READ_HOLDING, address, count)
        return self._registers(self._exchange(request, what, device))

    def read_input(self, device_id: int, address: int, count: int, *, device: str) -> list[int]:
        what = f"read input {address:#06x} x{count} @id {device_id}"
        request = mf.read_request(device_id, mf.READ_INPUT, address, count)
        return self._registers(self._exchange(request, what, device))

    @staticmethod
    def _registers(values: list[int] | None) -> list[int]:
        # parse_reply returns None only for writes, and a read request's reply was checked to be a read's.
        assert values is not None
        return values

    def write_register(self, device_id: int, address: int, value: int, *, device: str) -> None:
        what = f"write {address:#06x}={value:#06x} @id {device_id}"
        self._exchange(mf.write_single_request(device_id, address, to_unsigned16(value)), what, device)

    def write_registers(self, device_id: int, address: int, values: list[int], *, device: str) -> None:
        what = f"write {address:#06x}={[hex(v) for v in values]} @id {device_id}"
        regs = [to_unsigned16(v) for v in values]
        self._exchange(mf.write_multiple_request(device_id, address, regs), what, device)

    def raw_port(self):
        """The underlying port, for devices that leave Modbus for a binary stream (the
        FT300's stream mode). Hold ``lock`` while using it; prefer ``link``."""
        return self.link.port

    def close(self) -> None:
        self.link.close()
