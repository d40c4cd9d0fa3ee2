"""Robotiq FT300 six-axis force/torque sensor over Modbus RTU (19200 8N1, id 9).

Polled: six signed registers from 180, force = value/100 N, torque = value/1000 N·m
(= value N·mm). Stream mode (~100 Hz): write 0x0200 to register 410; the sensor
then sends 16-byte frames ``0x20 0x4E, six int16 LE, CRC-16/Modbus LE``; about 50
bytes of 0xFF end it.
"""

from __future__ import annotations

import struct

import numpy as np

from rig.clock import Clock
from rig.drivers.wrench_stream import STREAM_POLL_S, FrameSync, GaugeBase, drain
from rig.errors import DeviceDisconnected
from rig.transport.crc import crc_ok
from rig.transport.modbus_bus import ModbusBus, to_signed16
from rig.transport.serial_link import PORT_ERRORS

REG_WRENCH = 180
REG_STREAM = 410
STREAM_START = 0x0200
REG_FIRMWARE = 500  # 3 registers, ASCII, two characters each
REG_SERIAL = 510  # 2 registers, uint32 high word first
REG_YEAR = 514
FRAME_HEADER = b"\x20\x4e"
FRAME_LENGTH = 16
STOP_BYTES = b"\xff" * 50
# Counts to physical units: Fx Fy Fz in 1/100 N; Mx My Mz in 1/1000 N·m = 1 N·mm.
COUNTS_TO_UNITS = np.array([0.01, 0.01, 0.01, 1.0, 1.0, 1.0])


def decode_counts(counts) -> np.ndarray:
    return np.asarray(counts, dtype=np.float64) * COUNTS_TO_UNITS


def decode_stream_frame(frame: bytes) -> np.ndarray:
    return decode_counts(struct.unpack("<6h", frame[2:14]))


def encode_stream_frame(values: np.ndarray) -> bytes:
    """The frame a sensor sends for ``values`` (N, N·mm); used by the simulator and tests."""
    from rig.transport.crc import append_crc

    counts = np.clip(np.round(np.asarray(values) / COUNTS_TO_UNITS), -32768, 32767).astype(int)
    return append_crc(FRAME_HEADER + struct.pack("<6h", *counts))


class FT300(GaugeBase):
    def __init__(self, bus: ModbusBus, clock: Clock, *, name: str = "gauge", device_id: int = 9,
                 buffer_size: int = 4096, fresh_after_s: float = 0.05):
        super().__init__(clock, buffer_size, fresh_after_s=fresh_after_s)
        self.bus = bus
        self.name = name
        self.device_id = device_id
        self.label = f"{name} (Robotiq FT300 id {device_id} on {bus.url})"

    def make_sync(self) -> FrameSync:
        return FrameSync(FRAME_HEADER, FRAME_LENGTH, crc_ok)

    decode = staticmethod(decode_stream_frame)

    def _poll_raw(self) -> np.ndarray:
        regs = self.bus.read_holding(self.device_id, REG_WRENCH, 6, device=self.label)
        return decode_counts([to_signed16(r) for r in regs])

    def identify(self) -> dict:
        fw = self.bus.read_holding(self.device_id, REG_FIRMWARE, 3, device=self.label)
        serial = self.bus.read_holding(self.device_id, REG_SERIAL, 2, device=self.label)
        (year,) = self.bus.read_holding(self.device_id, REG_YEAR, 1, device=self.label)
        firmware = b"".join(r.to_bytes(2, "big") for r in fw).decode("ascii", "replace").strip("\x00 ")
        return {"firmware": firmware, "serial": (serial[0] << 16) | serial[1], "year": year}

    def _stream_open(self):
        self.bus.write_registers(self.device_id, REG_STREAM, [STREAM_START], device=self.label)
        link = self.bus.link
        self._saved_timeout, link.port.timeout = link.port.timeout, STREAM_POLL_S

        def read_chunk() -> bytes:
            # Through the link: bytes it read past the start-stream echo come first.
            try:
                return link.read_available()
            except DeviceDisconnected as exc:
                raise DeviceDisconnected(self.label, "stream read", None, f"stream port failed: {exc}") from exc

        return read_chunk

    def _stream_close(self) -> None:
        link = self.bus.link
        with self.bus.lock:
            link.write(STOP_BYTES, "stop stream", device=self.label)
            try:
                drain(link.port)  # frames still in flight
                link.port.timeout = self._saved_timeout
            except PORT_ERRORS as exc:
                raise DeviceDisconnected(self.label, "stop stream", None, str(exc)) from exc
            link.discard_input(device=self.label)
