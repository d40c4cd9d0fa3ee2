"""A simulated Robotiq FT300: Modbus registers and the binary stream mode.

Registers as the FT 300 manual lists them and Robotiq's ``rq_sensor_com.c`` reads
them: 180-185 the wrench (int16; N×100, N·m×1000), 410 stream start (0x0200), 500-502
firmware (3 ASCII characters, 3 version bytes), 510-513 serial (3 ASCII characters,
then a uint32: low word 512, high word 513), 514 production year. The identity values
themselves (FTS 1.0.3, serial 100001, 2024) are invented. ``streaming=True`` starts the
sensor in stream mode, as one left streaming by a crashed host is found.
"""

from __future__ import annotations

from rig.drivers import ft300 as ft
from rig.sim.modbus_rtu import ILLEGAL_DATA_ADDRESS, ILLEGAL_DATA_VALUE, ModbusException, RtuServer
from rig.sim.stream_clock import SampleSchedule
from rig.sim.world import SimWorld
from rig.transport.modbus_bus import to_unsigned16

STOP_RUN = 20  # consecutive 0xFF bytes that end stream mode (hosts send about 50)


FIRMWARE = b"FTS" + bytes([1, 0, 3])  # printed "FTS-1.0.3"
SERIAL_PREFIX = b"FTS\x00"  # 510 hi, 510 lo, 511 hi; 511 lo unused (ASSUMED 0)
SERIAL_NUMBER = 100001
PRODUCTION_YEAR = 2024


def _words(raw: bytes) -> list[int]:
    return [int.from_bytes(raw[i : i + 2], "big") for i in range(0, len(raw), 2)]


class _Registers:
    serves_inline = True  # pure computation on the simulated world (rig/sim/link.py: SimServer.inline)

    def __init__(self, sim: "Ft300Sim"):
        self.sim = sim
        serial = _words(SERIAL_PREFIX) + [SERIAL_NUMBER & 0xFFFF, SERIAL_NUMBER >> 16]  # 510-513
        self.fixed = {
            **{ft.REG_FIRMWARE + i: w for i, w in enumerate(_words(FIRMWARE))},  # 500-502
            **{ft.REG_SERIAL + i: w for i, w in enumerate(serial)},
            ft.REG_YEAR: PRODUCTION_YEAR,
        }

    def read_registers(self, address, count, now_s):
        out = []
        values = None
        for a in range(address, address + count):
            if ft.REG_WRENCH <= a < ft.REG_WRENCH + 6:
                if values is None:
                    values = self.sim.world.gauge_wrench(now_s) / ft.COUNTS_TO_UNITS
                out.append(to_unsigned16(int(max(-32768, min(32767, round(values[a - ft.REG_WRENCH]))))))
            elif a in self.fixed:
                out.append(self.fixed[a])
            else:
                raise ModbusException(ILLEGAL_DATA_ADDRESS)
        return out

    def write_registers(self, address, values, now_s):
        if address == ft.REG_STREAM and len(values) == 1:
            if values[0] != ft.STREAM_START:
                raise ModbusException(ILLEGAL_DATA_VALUE)
            self.sim.schedule.start(now_s)
            return
        raise ModbusException(ILLEGAL_DATA_ADDRESS)


class Ft300Sim(RtuServer):
    def __init__(self, world: SimWorld, *, device_id: int = 9, rate_hz: float = 100.0, streaming: bool = False):
        super().__init__({device_id: _Registers(self)})
        self.world = world
        self.schedule = SampleSchedule(rate_hz)
        self._ff_run = 0
        self._stream_at_first_tick = streaming  # started on the clock at the first tick

    @property
    def streaming(self) -> bool:
        return self._stream_at_first_tick or self.schedule.next_t is not None

    def feed(self, data: bytes, now_s: float) -> list[bytes]:
        if not self.streaming:
            return super().feed(data, now_s)
        for b in data:  # in stream mode only a run of 0xFF means anything
            self._ff_run = self._ff_run + 1 if b == 0xFF else 0
            if self._ff_run >= STOP_RUN:
                self.schedule.stop()
                self._stream_at_first_tick = False
                self._ff_run = 0
                self._buf = b""
                break
        return []

    def tick_interval_s(self):
        return min(0.005, self.schedule.period_s) if self.streaming else None

    def tick(self, now_s: float) -> list[bytes]:
        if self._stream_at_first_tick:
            self._stream_at_first_tick = False
            self.schedule.start(now_s)
        times = self.schedule.due(now_s)
        return ft.encode_stream_frames(self.world.gauge_samples(times)) if times else []
