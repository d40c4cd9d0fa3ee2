"""A simulated PR-mode Modbus drive moving one of the world's stages."""

from __future__ import annotations

from rig.drivers import pr_registers as reg
from rig.sim.modbus_rtu import ILLEGAL_DATA_ADDRESS, ILLEGAL_DATA_VALUE, ModbusException
from rig.sim.stage import SimStage, StageFault
from rig.transport.modbus_bus import join_int32, split_int32

STALL_ALARM = 0x0180  # the alarm the simulator raises for a stalled motor


class PrDriveSim:
    def __init__(self, stage: SimStage, *, pulses_per_rev: int, travel_per_rev: float):
        self.stage = stage
        self.travel_per_rev = travel_per_rev
        self.regs: dict[int, int] = {
            reg.PULSES_PER_REV: pulses_per_rev,
            reg.PR0_MODE: reg.MODE_ABSOLUTE,
            reg.PR0_POS_HIGH: 0, reg.PR0_POS_LOW: 0,
            reg.PR0_VELOCITY_RPM: 60, reg.PR0_ACCEL_MS: 100, reg.PR0_DECEL_MS: 100,
            reg.JOG: 0,
        }
        self.zero_pulses = 0  # set by CTRL_SET_ZERO: command position 0 here
        self.homed_since_power_up = stage.homed

    @property
    def pulse(self) -> float:
        return self.travel_per_rev / self.regs[reg.PULSES_PER_REV]

    def _pulses(self, now_s: float) -> int:
        return round(self.stage.position(now_s) / self.pulse) - self.zero_pulses

    def read_registers(self, address: int, count: int, now_s: float) -> list[int]:
        out = []
        for a in range(address, address + count):
            if a == reg.PR_CONTROL:
                busy = self.stage.busy(now_s)
                if not busy and self.stage.homed:
                    self.homed_since_power_up = True
                out.append((reg.STATUS_RUNNING if busy else 0) | (reg.STATUS_HOMED if self.homed_since_power_up else 0))
            elif a in (reg.COMMAND_POS_HIGH, reg.COMMAND_POS_LOW):
                high, low = split_int32(self._pulses(now_s))
                out.append(high if a == reg.COMMAND_POS_HIGH else low)
            elif a == reg.ALARM_CODE:
                out.append(STALL_ALARM if self.stage.stalled else 0)
            elif a in self.regs:
                out.append(self.regs[a])
            else:
                raise ModbusException(ILLEGAL_DATA_ADDRESS)
        return out

    def write_registers(self, address: int, values: list[int], now_s: float) -> None:
        for offset, value in enumerate(values):
            a = address + offset
            if a == reg.PR_CONTROL:
                self._control(value, now_s)
            elif a in self.regs and a not in (reg.PULSES_PER_REV,):
                self.regs[a] = value
            elif a == reg.PULSES_PER_REV:
                if value <= 0:
                    raise ModbusException(ILLEGAL_DATA_VALUE)
                self.regs[a] = value
            else:
                raise ModbusException(ILLEGAL_DATA_ADDRESS)

    def _control(self, value: int, now_s: float) -> None:
        if value == reg.CTRL_TRIGGER_PR0:
            mode = self.regs[reg.PR0_MODE]
            target_pulses = join_int32(self.regs[reg.PR0_POS_HIGH], self.regs[reg.PR0_POS_LOW])
            if mode == reg.MODE_RELATIVE:
                target_pulses += self._pulses(now_s)
            elif mode != reg.MODE_ABSOLUTE:
                raise ModbusException(ILLEGAL_DATA_VALUE)
            speed = self.regs[reg.PR0_VELOCITY_RPM] / 60.0 * self.travel_per_rev
            try:
                self.stage.move_to((target_pulses + self.zero_pulses) * self.pulse, speed, now_s)
            except StageFault as exc:
                raise ModbusException(ILLEGAL_DATA_VALUE) from exc
        elif value == reg.CTRL_HOME:
            self.stage.home(now_s)
        elif value == reg.CTRL_SET_ZERO:
            self.zero_pulses = round(self.stage.position(now_s) / self.pulse)
        elif value == reg.CTRL_EMERGENCY_STOP:
            self.stage.stop(now_s)
        else:
            raise ModbusException(ILLEGAL_DATA_VALUE)
