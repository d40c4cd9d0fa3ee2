"""Robotiq FT300 six-axis force/torque sensor over Modbus RTU (19200 8N1, id 9).

Polled: six signed registers from 180, force = value/100 N, torque = value/1000 N·m
(= value N·mm). Stream mode (~100 Hz): write 0x0200 to register 410; the sensor
then sends 16-byte frames ``0x20 0x4E, six int16 LE, CRC-16/Modbus LE``; about 50
bytes of 0xFF end it.

Sources: Robotiq's C driver ``rq_sensor_com.c`` (BSD, in robotiq_ft_sensor; frame
decoding, CRC over 14 bytes, the 50-byte 0xFF "jam signal", identification) and the
FT 300 manual's register table (180–185, 410, 500–502 firmware, 510–513 serial, 514
year). A sensor left streaming (the host crashed) ignores Modbus: opening the driver
first listens, and if the line is not quiet sends the jam signal until it is, as
Robotiq's ``rq_com_tentative_connexion`` does.
"""

from __future__ import annotations

import struct

import numpy as np

from rig.clock import Clock
from rig.drivers.gauge_base import GaugeBase
from rig.drivers.wrench_stream import STREAM_POLL_S, FrameSync, drain
from rig.errors import DeviceDisconnected, DeviceTimeout
from rig.transport.crc import crc_ok
from rig.transport.modbus_bus import ModbusBus, to_signed16
from rig.transport.serial_link import PORT_ERRORS

REG_WRENCH = 180
REG_STREAM = 410
STREAM_START = 0x0200
REG_FIRMWARE = 500  # 500-502: 3 ASCII characters, then 3 version bytes -> "FTS-1.0.3"
REG_SERIAL = 510  # 510-513: 3 ASCII characters (510 hi, lo, 511 hi); uint32 low word 512, high word 513
REG_YEAR = 514
FRAME_HEADER = b"\x20\x4e"
FRAME_LENGTH = 16
STOP_BYTES = b"\xff" * 50  # rq_sensor_com.c: RQ_COM_JAM_SIGNAL_CHAR × RQ_COM_JAM_SIGNAL_LENGTH
# rq_sensor_com.c takes 80 ms without a byte as "no stream"; listen a little longer.
QUIET_S = 0.1
STOP_TRIES = 5  # jam signals sent before a sensor that keeps streaming is an error
# After a jam signal, this many bytes without a quiet gap means the stream goes on
# (about 0.3 s of frames at 100 Hz).
STREAM_BYTES_LIMIT = 32 * FRAME_LENGTH
# Counts to physical units: Fx Fy Fz in 1/100 N; Mx My Mz in 1/1000 N·m = 1 N·mm.
COUNTS_TO_UNITS = np.array([0.01, 0.01, 0.01, 1.0, 1.0, 1.0])


def decode_counts(counts) -> np.ndarray:
    return np.asarray(counts, dtype=np.float64) * COUNTS_TO_UNITS


def decode_firmware(regs: list[int]) -> str:
    """Registers 500-502 as Robotiq prints them: ``%c%c%c-%u.%u.%u`` ("FTS-1.0.3")."""
    raw = b"".join(r.to_bytes(2, "big") for r in regs)
    return f"{raw[0:3].decode('ascii', 'replace')}-{raw[3]}.{raw[4]}.{raw[5]}"


def decode_serial(regs: list[int]) -> tuple[str, int]:
    """Registers 510-513: (the printed serial ``%c%c%c-%.4u``, or "UNKNOWN" for 0; the number)."""
    number = (regs[3] << 16) | regs[2]  # low word in 512, high word in 513
    if number == 0:
        return "UNKNOWN", 0
    prefix = b"".join(r.to_bytes(2, "big") for r in regs[:2])[:3].decode("ascii", "replace")
    return f"{prefix}-{number:04d}", number


def decode_stream_frame(frame: bytes) -> np.ndarray:
    return decode_counts(struct.unpack("<6h", frame[2:14]))


def encode_stream_frame(values: np.ndarray) -> bytes:
    """The frame a sensor sends for ``values`` (N, N·mm); used by the simulator and tests."""
    return encode_stream_frames(np.asarray(values, dtype=np.float64).reshape(1, 6))[0]


def encode_stream_frames(values: np.ndarray) -> list[bytes]:
    """The frames for each row of ``values`` (n, 6): counts rounded to the wire's units and
    clipped to int16, little-endian, then the CRC (a simulator sends many per tick)."""
    from rig.transport.crc import append_crc

    counts = np.clip(np.round(np.asarray(values, dtype=np.float64) / COUNTS_TO_UNITS), -32768, 32767)
    return [append_crc(FRAME_HEADER + row.tobytes()) for row in counts.astype("<i2")]


class FT300(GaugeBase):
    def __init__(
        self,
        bus: ModbusBus,
        clock: Clock,
        *,
        name: str = "gauge",
        device_id: int = 9,
        buffer_size: int = 4096,
        fresh_after_s: float = 0.05,
    ):
        super().__init__(clock, buffer_size, fresh_after_s=fresh_after_s)
        self.bus = bus
        self.name = name
        self.device_id = device_id
        self.label = f"{name} (Robotiq FT300 id {device_id} on {bus.url})"
        self.stopped_stream_at_open = self.stop_leftover_stream()

    def _listen(self, limit_bytes: int) -> tuple[int, bool]:
        """Bytes heard until the line is quiet for QUIET_S (then True), or until
        ``limit_bytes`` arrived without such a gap (then False: still streaming)."""
        port = self.bus.link.port
        saved, port.timeout = port.timeout, QUIET_S
        try:
            heard = 0
            while heard < limit_bytes:
                first = port.read(1)
                if not first:
                    return heard, True
                waiting = port.in_waiting
                heard += 1 + len(port.read(waiting) if waiting else b"")
            return heard, False
        finally:
            port.timeout = saved

    def stop_leftover_stream(self) -> bool:
        """Stop a stream the sensor kept up from an earlier session; True if there was one.

        Listen; if anything arrives, send 50 × 0xFF and listen again, up to STOP_TRIES
        times. DeviceTimeout if the sensor keeps streaming, DeviceDisconnected if the
        port fails.
        """
        link = self.bus.link
        with self.bus.lock:
            try:
                heard, quiet = self._listen(FRAME_LENGTH)
                if heard == 0:
                    return False
                for _ in range(STOP_TRIES):
                    link.write(STOP_BYTES, "stop leftover stream", device=self.label)
                    heard, quiet = self._listen(STREAM_BYTES_LIMIT)
                    if quiet:
                        link.discard_input(device=self.label)
                        return True
            except PORT_ERRORS as exc:
                raise DeviceDisconnected(self.label, "listen for a leftover stream", None, str(exc)) from exc
        raise DeviceTimeout(
            self.label,
            "stop leftover stream (50 x 0xFF)",
            None,
            f"sensor still streaming after {STOP_TRIES} stop signals ({heard} bytes after the last)",
        )

    def make_sync(self) -> FrameSync:
        return FrameSync(FRAME_HEADER, FRAME_LENGTH, crc_ok)

    decode = staticmethod(decode_stream_frame)

    def _poll_raw(self) -> np.ndarray:
        regs = self.bus.read_holding(self.device_id, REG_WRENCH, 6, device=self.label)
        return decode_counts([to_signed16(r) for r in regs])

    def identify(self) -> dict:
        """Firmware ("FTS-1.0.3"), serial ("FTS-0042" or "UNKNOWN"), its number, production year."""
        fw = self.bus.read_holding(self.device_id, REG_FIRMWARE, 3, device=self.label)
        serial_regs = self.bus.read_holding(self.device_id, REG_SERIAL, 4, device=self.label)
        (year,) = self.bus.read_holding(self.device_id, REG_YEAR, 1, device=self.label)
        serial, number = decode_serial(serial_regs)
        return {"firmware": decode_firmware(fw), "serial": serial, "serial_number": number, "year": year}

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

    def _stream_in_flight(self):
        link = self.bus.link
        return link.in_flight if link.has_peer() else None

    def _stream_inline(self):
        # Only against an inline-served simulator in this process (a pty on the discrete
        # clock, rig/sim/link.py): hardware, tcp and `rig sim serve`'s clients keep the
        # reader thread alone.
        link = self.bus.link
        if not link.inline_peer() or not link.can_wait_readable():
            return None

        def take() -> bytes:
            try:
                return link.read_waiting()
            except DeviceDisconnected as exc:
                raise DeviceDisconnected(self.label, "stream read", None, f"stream port failed: {exc}") from exc

        return link.wait_readable, take, link.in_flight

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
