"""A simulated Robotiq FT300: Modbus registers and the binary stream mode."""

from __future__ import annotations

from rig.drivers import ft300 as ft
from rig.sim.modbus_rtu import ILLEGAL_DATA_ADDRESS, ILLEGAL_DATA_VALUE, ModbusException, RtuServer
from rig.sim.stream_clock import SampleSchedule
from rig.sim.world import SimWorld
from rig.transport.modbus_bus import to_unsigned16

STOP_RUN = 20  # consecutive 0xFF bytes that end stream mode (hosts send about 50)


class _Registers:
    def __init__(self, sim: "Ft300Sim"):
        self.sim = sim
        fw = b"FT3.04"
        self.fixed = {
            ft.REG_FIRMWARE: int.from_bytes(fw[0:2], "big"),
            ft.REG_FIRMWARE + 1: int.from_bytes(fw[2:4], "big"),
            ft.REG_FIRMWARE + 2: int.from_bytes(fw[4:6], "big"),
            ft.REG_SERIAL: 0x0001, ft.REG_SERIAL + 1: 0x86A1, ft.REG_YEAR: 2024,
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
    def __init__(self, world: SimWorld, *, device_id: int = 9, rate_hz: float = 100.0):
        super().__init__({device_id: _Registers(self)})
        self.world = world
        self.schedule = SampleSchedule(rate_hz)
        self._ff_run = 0

    @property
    def streaming(self) -> bool:
        return self.schedule.next_t is not None

    def feed(self, data: bytes, now_s: float) -> list[bytes]:
        if not self.streaming:
            return super().feed(data, now_s)
        for b in data:  # in stream mode only a run of 0xFF means anything
            self._ff_run = self._ff_run + 1 if b == 0xFF else 0
            if self._ff_run >= STOP_RUN:
                self.schedule.stop()
                self._ff_run = 0
                self._buf = b""
                break
        return []

    def tick_interval_s(self):
        return min(0.005, self.schedule.period_s) if self.streaming else None

    def tick(self, now_s: float) -> list[bytes]:
        times = self.schedule.due(now_s)
        return [ft.encode_stream_frame(w) for w in self.world.gauge_samples(times)]
