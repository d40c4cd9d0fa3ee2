"""SRI M8128 six-axis interface over serial (115200) or TCP (port 4008).

From SRI's M8128 manual (command section "GSD", its worked ``AT+GOD`` example, and
the "Step 1 SMPF, Step 2 GOD/GSD" procedure): ASCII commands end in CR LF
(``AT+SMPF=<Hz>``, ``AT+DCKMD=SUM``, ``AT+GOD`` one sample, ``AT+GSD`` stream,
``AT+GSD=STOP``); settings are answered ``ACK+<cmd>=<value>$OK\\r\\n``. A data frame
is ``0xAA 0x55, PackageLength (u16 BE) = 2 + 6×4×1 + 1 = 27, PackageNo (u16 BE, 0 to
65535 then wraps: gaps are lost packets), six float32 LE, SUM`` where SUM is the low
byte of the sum of the 24 data bytes only. Values are engineering units of the
decoupling matrix: N and N·m on SRI-calibrated sensors (converted to N·mm here).
"""

from __future__ import annotations

import struct

import numpy as np

from rig.clock import Clock
from rig.drivers.gauge_base import GaugeBase
from rig.drivers.wrench_stream import STREAM_POLL_S, FrameSync, drain
from rig.errors import DeviceRejected, FramingError
from rig.transport.serial_link import SerialLink

FRAME_HEADER = b"\xaa\x55"
FRAME_LENGTH = 31  # header 2 + length 2 + packet 2 + data 24 + sum 1
PAYLOAD_LENGTH = 27
UNITS = np.array([1.0, 1.0, 1.0, 1000.0, 1000.0, 1000.0])  # N, N, N, N·m→N·mm ×3


def frame_valid(frame: bytes) -> bool:
    """Header, length, sum byte, and six finite numbers: a NaN frame is never a value."""
    if len(frame) != FRAME_LENGTH or frame[:2] != FRAME_HEADER:
        return False
    if int.from_bytes(frame[2:4], "big") != PAYLOAD_LENGTH:
        return False
    if sum(frame[6:30]) & 0xFF != frame[30]:
        return False
    return bool(np.all(np.isfinite(struct.unpack("<6f", frame[6:30]))))


def packet_number(frame: bytes) -> int:
    return int.from_bytes(frame[4:6], "big")


SEQUENCE_WINDOW = 64  # a packet-number jump beyond this is a resync, not a loss


class PacketSync(FrameSync):
    """Frames in packet-number order: a small jump counts lost packets, a repeat is dropped.

    The SUM byte does not cover the packet number, so a corrupted number passes the
    sum; a jump beyond ``SEQUENCE_WINDOW`` either way is counted as a resync and the
    frame kept, so one bad number cannot make the following frames look old.
    """

    def __init__(self):
        super().__init__(FRAME_HEADER, FRAME_LENGTH, frame_valid)
        self.last_packet: int | None = None
        self.lost = self.out_of_order = self.resyncs = 0

    def feed(self, data: bytes) -> list[bytes]:
        out = []
        for frame in super().feed(data):
            n = packet_number(frame)
            if self.last_packet is not None:
                step = (n - self.last_packet + 0x8000) % 0x10000 - 0x8000  # 0..65535 wraps
                if -SEQUENCE_WINDOW < step <= 0:
                    self.out_of_order += 1
                    continue
                if 0 < step <= SEQUENCE_WINDOW:
                    self.lost += step - 1
                else:
                    self.resyncs += 1
            self.last_packet = n
            out.append(frame)
        return out


def decode_frame(frame: bytes) -> np.ndarray:
    return np.array(struct.unpack("<6f", frame[6:30]), dtype=np.float64) * UNITS


def encode_frame(values: np.ndarray, packet: int) -> bytes:
    """The frame the interface sends for ``values`` (N, N·mm); for the simulator and tests."""
    data = struct.pack("<6f", *(np.asarray(values, dtype=np.float64) / UNITS))
    return FRAME_HEADER + struct.pack(">HH", PAYLOAD_LENGTH, packet & 0xFFFF) + data + bytes([sum(data) & 0xFF])


class M8128(GaugeBase):
    def __init__(
        self,
        link: SerialLink,
        clock: Clock,
        *,
        name: str = "gauge",
        rate_hz: int = 100,
        buffer_size: int = 4096,
        fresh_after_s: float = 0.05,
    ):
        super().__init__(clock, buffer_size, fresh_after_s=fresh_after_s)
        self.link = link
        self.name = name
        self.rate_hz = rate_hz
        self.label = f"{name} (SRI M8128 on {link.url})"

    def make_sync(self) -> PacketSync:
        return PacketSync()

    def stream_stats(self) -> dict:
        stats = super().stream_stats()
        sync = self._reader.sync if self._reader else None
        stats.update({k: getattr(sync, k) if sync else 0 for k in ("lost", "out_of_order", "resyncs")})
        return stats

    decode = staticmethod(decode_frame)

    def command(self, text: str) -> str:
        """Send an AT command and return its ACK line; a missing ``$OK`` is a rejection."""
        with self.link.lock:
            self.link.discard_input()
            self.link.write(f"{text}\r\n".encode("ascii"), text)
            reply = self.link.read_until(b"\r\n", text).decode("ascii", "replace").strip()
        if not reply.startswith("ACK+") or not reply.endswith("$OK"):
            raise DeviceRejected(self.label, text, reply, "no $OK acknowledgement")
        return reply

    def configure(self) -> None:
        self.command(f"AT+SMPF={self.rate_hz}")
        self.command("AT+DCKMD=SUM")

    def _poll_raw(self) -> np.ndarray:
        with self.link.lock:
            self.link.discard_input()
            self.link.write(b"AT+GOD\r\n", "AT+GOD")
            frame = self.link.read_exact(FRAME_LENGTH, "AT+GOD")
        if not frame_valid(frame):
            raise FramingError(self.label, "AT+GOD", frame, "bad header, length, sum byte or a non-finite value")
        return decode_frame(frame)

    def _stream_open(self):
        with self.link.lock:
            self.link.discard_input()
            self.link.write(b"AT+GSD\r\n", "AT+GSD")
            self._saved_timeout, self.link.port.timeout = self.link.port.timeout, STREAM_POLL_S
        return self.link.read_available

    def _stream_close(self) -> None:
        with self.link.lock:
            self.link.write(b"AT+GSD=STOP\r\n", "AT+GSD=STOP")
            drain(self.link.port)  # frames still in flight
            self.link.port.timeout = self._saved_timeout
