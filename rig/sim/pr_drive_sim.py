"""A simulated PR-mode Modbus drive moving one of the world's stages.

Answers the registers ``rig/drivers/pr_registers.py`` documents (sources there): the
eight PR0 registers, written one by one or in the manual's single function-16 frame
whose last register (0x6207) triggers the path; 0x6002 commands; the 0x1003 motion
state and the 0x1012–0x1015 positions. Anything else is ILLEGAL DATA ADDRESS.
"""

from __future__ import annotations

from rig.drivers import pr_registers as reg
from rig.sim.modbus_rtu import ILLEGAL_DATA_ADDRESS, ILLEGAL_DATA_VALUE, ModbusException
from rig.sim.stage import SimStage, StageFault
from rig.transport.modbus_bus import join_int32, split_int32

STALL_ALARM = 0x0180  # the alarm code the simulator reports for a stalled motor (ASSUMED code)
PR0_REGISTERS = range(reg.PR0_MODE, reg.PR0_MODE + reg.PR0_LENGTH)
# Stopping (docs/simulator.md, "Stopping"). 0x0040 on 0x6002 is an emergency stop: the drive
# ramps down at its emergency-stop deceleration. ASSUMED (neither its Pr parameter nor its
# default is in the manual pages at hand): 50 ms per 1000 rpm, the unit of the PR0 ramps
# (pr_registers.py), i.e. 1333 deg/s² on the simulated rig's 4 deg/rev worm stage.
EMERGENCY_DECEL_MS_PER_KRPM = 50
# The drive acts on a request once the RTU frame has ended: 3.5 characters of silence, a
# fixed 1.75 ms above 19200 baud (Modbus over Serial Line v1.02 §2.5.1.1; the drive's
# default wire is 38400 baud), plus its command processing, ASSUMED 2 ms.
FRAME_GAP_S = 0.00175
PROCESSING_S = 0.002


class PrDriveSim:
    serves_inline = True  # pure computation on the simulated stage (rig/sim/link.py: SimServer.inline)

    def __init__(self, stage: SimStage, *, pulses_per_rev: int, travel_per_rev: float):
        self.stage = stage
        self.travel_per_rev = travel_per_rev
        self.regs: dict[int, int] = {
            reg.PULSES_PER_REV: pulses_per_rev,
            reg.PR0_MODE: reg.MODE_ABSOLUTE,
            reg.PR0_POS_HIGH: 0,
            reg.PR0_POS_LOW: 0,
            reg.PR0_VELOCITY_RPM: 60,
            reg.PR0_ACCEL_MS: 100,
            reg.PR0_DECEL_MS: 100,
            reg.PR0_DELAY_MS: 0,
            reg.PR0_TRIGGER: 0,
            reg.PR_CONTROL: 0,  # ASSUMED: a read returns the last command written
            reg.JOG: 0,
            reg.PR_CONTROL_SETTING: 0,  # software limits disabled
            reg.SOFT_LIMIT_POS_HIGH: 0,
            reg.SOFT_LIMIT_POS_LOW: 0,
            reg.SOFT_LIMIT_NEG_HIGH: 0,
            reg.SOFT_LIMIT_NEG_LOW: 0,
        }
        self.zero_pulses = 0  # set by CTRL_SET_ZERO: command position 0 here
        self.homed_since_power_up = stage.homed
        self.commanded = False  # a path or homing was triggered since power-up
        emergency = krpm_ramp(EMERGENCY_DECEL_MS_PER_KRPM, travel_per_rev)
        stage.configure(stop_decel=emergency, abrupt_decel=emergency, stop_reaction_s=FRAME_GAP_S + PROCESSING_S)

    @property
    def pulse(self) -> float:
        return self.travel_per_rev / self.regs[reg.PULSES_PER_REV]

    def _pulses(self, now_s: float) -> int:
        return round(self.stage.position(now_s) / self.pulse) - self.zero_pulses

    def motion_state(self, now_s: float) -> int:
        """0x1003: bit0 fault, bit1 enabled, bit2 running, bit4/bit5 command/path done, bit6 homed."""
        busy = self.stage.busy(now_s)
        if not busy and self.stage.homed:
            self.homed_since_power_up = True
        state = reg.STATE_ENABLED  # the simulated drive is always enabled
        if self.stage.stalled:
            state |= reg.STATE_FAULT
        if busy:
            state |= reg.STATE_RUNNING
        elif self.commanded:
            state |= reg.STATE_COMMAND_DONE | reg.STATE_PATH_DONE
        if self.homed_since_power_up:
            state |= reg.STATE_HOMED
        return state

    def read_registers(self, address: int, count: int, now_s: float) -> list[int]:
        out = []
        for a in range(address, address + count):
            if a == reg.MOTION_STATE:
                out.append(self.motion_state(now_s))
            elif a in (reg.COMMAND_POS_HIGH, reg.COMMAND_POS_LOW, reg.FEEDBACK_POS_HIGH, reg.FEEDBACK_POS_LOW):
                high, low = split_int32(self._pulses(now_s))  # no following error in the simulation
                out.append(high if a in (reg.COMMAND_POS_HIGH, reg.FEEDBACK_POS_HIGH) else low)
            elif a == reg.ALARM_CODE:
                out.append(STALL_ALARM if self.stage.stalled else 0)
            elif a in self.regs:
                out.append(self.regs[a])
            else:
                raise ModbusException(ILLEGAL_DATA_ADDRESS)
        return out

    def write_registers(self, address: int, values: list[int], now_s: float) -> None:
        addresses = range(address, address + len(values))
        if any(a not in self.regs for a in addresses):
            raise ModbusException(ILLEGAL_DATA_ADDRESS)  # nothing is written
        for a, value in zip(addresses, values):
            if a in (reg.PR_CONTROL, reg.PR0_TRIGGER):  # Pr9.07 is mapped to Pr8.02 [CS2RS]
                self.regs[a] = value
                self._control(value, now_s)
            elif a == reg.PULSES_PER_REV:
                if value <= 0:
                    raise ModbusException(ILLEGAL_DATA_VALUE)
                self.regs[a] = value
            else:
                self.regs[a] = value

    def _control(self, value: int, now_s: float) -> None:
        if value == reg.CTRL_TRIGGER_PR0:
            self.commanded = True
            mode = self.regs[reg.PR0_MODE]
            target_pulses = join_int32(self.regs[reg.PR0_POS_HIGH], self.regs[reg.PR0_POS_LOW])
            if mode == reg.MODE_RELATIVE:
                target_pulses += self._pulses(now_s)
            elif mode != reg.MODE_ABSOLUTE:
                raise ModbusException(ILLEGAL_DATA_VALUE)
            rpm = self.regs[reg.PR0_VELOCITY_RPM]
            if rpm == 0:
                return  # ASSUMED: a 0 rpm path ends where it starts (the manual's own example sends 0)
            speed = rpm / 60.0 * self.travel_per_rev
            target_pulses = self._inside_soft_limits(target_pulses)
            try:
                self.stage.move_to((target_pulses + self.zero_pulses) * self.pulse, speed, now_s)
            except StageFault as exc:
                raise ModbusException(ILLEGAL_DATA_VALUE) from exc
        elif value == reg.CTRL_HOME:
            self.commanded = True
            self.stage.home(now_s)
        elif value == reg.CTRL_SET_ZERO:
            self.zero_pulses = round(self.stage.position(now_s) / self.pulse)
        elif value == reg.CTRL_EMERGENCY_STOP:
            self.stage.stop(now_s, abrupt=True)
        elif value != 0:
            raise ModbusException(ILLEGAL_DATA_VALUE)

    def soft_limits(self) -> tuple[int, int] | None:
        """(negative, positive) software limits in pulses when enabled (registers ASSUMED)."""
        if not self.regs[reg.PR_CONTROL_SETTING] & reg.SOFT_LIMIT_ENABLE:
            return None
        r = self.regs
        return (
            join_int32(r[reg.SOFT_LIMIT_NEG_HIGH], r[reg.SOFT_LIMIT_NEG_LOW]),
            join_int32(r[reg.SOFT_LIMIT_POS_HIGH], r[reg.SOFT_LIMIT_POS_LOW]),
        )

    def _inside_soft_limits(self, target_pulses: int) -> int:
        """A path that would pass an enabled software limit stops at it (ASSUMED, pr_registers.py)."""
        limits = self.soft_limits()
        if limits is None:
            return target_pulses
        return min(max(target_pulses, limits[0]), limits[1])


def krpm_ramp(ms_per_krpm: float, travel_per_rev: float) -> float:
    """A drive ramp given as ms per 1000 rpm, in stage units/s²."""
    return 1000.0 / 60.0 * abs(travel_per_rev) / (ms_per_krpm / 1000.0)
