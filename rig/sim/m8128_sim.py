"""A simulated SRI M8128 interface: AT commands, single samples and streaming.

Follows SRI's M8128 manual where it speaks (frame layout, SUM over the data bytes,
packet numbers from 0 wrapping after 65535, ``ACK+DCKMD=SUM$OK``); what it does not
show is assumed and listed in docs/hardware.md ("SRI M8128: sources").
"""

from __future__ import annotations

from rig.drivers import m8128 as m8
from rig.sim.stream_clock import SampleSchedule
from rig.sim.world import SimWorld


class M8128Sim:
    serves_inline = True  # pure computation on the simulated world (rig/sim/link.py: SimServer.inline)

    def __init__(self, world: SimWorld, *, rate_hz: float = 100.0):
        self.world = world
        self.rate_hz = rate_hz
        self.schedule = SampleSchedule(rate_hz)
        self.packet = 0  # the number of the next frame: the manual counts from 0
        self._buf = b""

    def _frame(self, values) -> bytes:
        frame = m8.encode_frame(values, self.packet)
        self.packet = (self.packet + 1) & 0xFFFF
        return frame

    def feed(self, data: bytes, now_s: float) -> list[bytes]:
        self._buf += data
        out = []
        while b"\r\n" in self._buf:
            line, self._buf = self._buf.split(b"\r\n", 1)
            out.extend(self._command(line.decode("ascii", "replace").strip(), now_s))
        return out

    def _command(self, cmd: str, now_s: float) -> list[bytes]:
        if cmd == "AT+SMPF=?":  # assumed: a query is answered like a setting
            return [f"ACK+SMPF={self.rate_hz:g}$OK\r\n".encode()]
        if cmd.startswith("AT+SMPF="):
            try:
                rate = int(cmd.split("=", 1)[1])
            except ValueError:
                return ["ACK+SMPF=ERROR$ERROR\r\n".encode()]
            if not 1 <= rate <= 2000:
                return [f"ACK+SMPF={rate}$ERROR\r\n".encode()]
            self.rate_hz = rate
            self.schedule = SampleSchedule(rate, report_on_advance=self.schedule.report_on_advance)
            return [f"ACK+SMPF={rate}$OK\r\n".encode()]
        if cmd == "AT+DCKMD=SUM":
            return [b"ACK+DCKMD=SUM$OK\r\n"]
        if cmd == "AT+GOD":
            return [self._frame(self.world.gauge_wrench(now_s))]
        if cmd == "AT+GSD":
            self.schedule.start(now_s)
            return []
        if cmd == "AT+GSD=STOP":
            self.schedule.stop()
            return []
        return [f"ACK+{cmd[3:] if cmd.startswith('AT+') else cmd}$ERROR\r\n".encode()]

    def tick_interval_s(self):
        return min(0.005, self.schedule.period_s) if self.schedule.next_t is not None else None

    def tick(self, now_s: float) -> list[bytes]:
        return [self._frame(w) for w in self.world.gauge_samples(self.schedule.due(now_s))]
