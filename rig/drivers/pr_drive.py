"""A Modbus RTU stepper/servo drive in PR (path) mode as one rig axis.

``position = pulses * scale + offset`` with ``scale = travel_per_rev / pulses_per_rev``
(mm or deg per pulse). A move is the manual's "immediate trigger": path 0 (mode,
target, speed, ramps, delay, and 0x10 in Pr9.07, which is mapped to the trigger
register) in one function-16 request. Status and position are read from the status
monitoring registers 0x1003 and 0x1012/0x1013. Registers and their sources:
``pr_registers.py``.
"""

from __future__ import annotations

import math

from rig.drivers import pr_registers as reg
from rig.errors import DeviceFault, DeviceRejected
from rig.transport.modbus_bus import ModbusBus, join_int32, split_int32
from rig.types import AxisStatus, MotionState


class PrDriveAxis:
    def __init__(
        self,
        bus: ModbusBus,
        *,
        name: str,
        device_id: int,
        pulses_per_rev: int,
        travel_per_rev: float,
        offset: float = 0.0,
        unit: str = "mm",
        accel_ms_per_krpm: int = 100,
        requires_home: bool = True,
    ):
        if pulses_per_rev <= 0 or travel_per_rev == 0:
            raise ValueError(f"axis {name}: pulses_per_rev must be > 0 and travel_per_rev non-zero")
        self.bus = bus
        self.name = name
        self.device_id = device_id
        self.pulses_per_rev = pulses_per_rev
        self.travel_per_rev = travel_per_rev
        self.scale = travel_per_rev / pulses_per_rev
        self.offset = offset
        self.unit = unit
        self.accel_ms_per_krpm = accel_ms_per_krpm
        self.requires_home = requires_home
        self.label = f"{name} (PR drive id {device_id} on {bus.url})"

    # native units, in one place
    def to_native(self, position: float) -> int:
        return round((position - self.offset) / self.scale)

    def to_position(self, pulses: int) -> float:
        return pulses * self.scale + self.offset

    def speed_to_rpm(self, speed: float) -> int:
        """Whole rpm (the drive's resolution), at least 1 (``min_speed``)."""
        return max(1, round(abs(speed / self.travel_per_rev) * 60.0))

    @property
    def min_speed(self) -> float:
        """The slowest speed the drive runs (1 rpm), unit/s: a slower one cannot be commanded."""
        return abs(self.travel_per_rev) / 60.0

    def _read(self, address: int, count: int) -> list[int]:
        return self.bus.read_holding(self.device_id, address, count, device=self.label)

    def _write(self, address: int, values: list[int]) -> None:
        if len(values) == 1:
            self.bus.write_register(self.device_id, address, values[0], device=self.label)
        else:
            self.bus.write_registers(self.device_id, address, values, device=self.label)

    def check_pulses_per_rev(self) -> None:
        """Refuse to run if the drive's pulses/rev differ from the config (wrong scale)."""
        (value,) = self._read(reg.PULSES_PER_REV, 1)
        if value != self.pulses_per_rev:
            raise DeviceFault(
                self.label,
                "read pulses per rev",
                value,
                f"drive is set to {value} pulses/rev but the config says {self.pulses_per_rev}",
            )

    def position(self) -> float:
        high, low = self._read(reg.COMMAND_POS_HIGH, 2)
        return self.to_position(join_int32(high, low))

    def _alarm(self) -> str:
        """The alarm warning once 0x1003 reports a fault; the code register is assumed,
        so a drive that rejects it still reports the fault."""
        try:
            (alarm,) = self._read(reg.ALARM_CODE, 1)
        except DeviceRejected as exc:
            return f"ALARM (fault bit set; code register 0x{reg.ALARM_CODE:04X} rejected: {exc.reason})"
        return f"ALARM 0x{alarm:04X}"

    def status(self) -> AxisStatus:
        (state,) = self._read(reg.MOTION_STATE, 1)
        warnings = (self._alarm(),) if state & reg.STATE_FAULT else ()
        return AxisStatus(
            position=self.position(),
            state=MotionState.BUSY if state & reg.STATE_RUNNING else MotionState.IDLE,
            homed=bool(state & reg.STATE_HOMED) or not self.requires_home,
            warnings=warnings,
        )

    def faults(self, status: AxisStatus) -> list[str]:
        return [w for w in status.warnings if w.startswith("ALARM")]

    def move_to(self, target: float, speed: float) -> None:
        high, low = split_int32(self.to_native(target))
        # One frame, Pr9.00..Pr9.07; the last register triggers PR0 as it is written.
        self._write(
            reg.PR0_MODE,
            [
                reg.MODE_ABSOLUTE,
                high,
                low,
                self.speed_to_rpm(speed),
                self.accel_ms_per_krpm,
                self.accel_ms_per_krpm,
                0,
                reg.CTRL_TRIGGER_PR0,
            ],
        )

    def stop(self) -> None:
        self._write(reg.PR_CONTROL, [reg.CTRL_EMERGENCY_STOP])

    def home(self) -> None:
        self._write(reg.PR_CONTROL, [reg.CTRL_HOME])

    # -- the drive's own software travel limits (rig/device_floor.py; registers ASSUMED) ---------
    def native_limits(self) -> tuple[int, int]:
        """(negative, positive) software limits in pulses; the int32 extremes while disabled."""
        (control,) = self._read(reg.PR_CONTROL_SETTING, 1)
        if not control & reg.SOFT_LIMIT_ENABLE:
            return reg.INT32_MIN, reg.INT32_MAX
        pos_high, pos_low, neg_high, neg_low = self._read(reg.SOFT_LIMIT_POS_HIGH, 4)
        return join_int32(neg_high, neg_low), join_int32(pos_high, pos_low)

    def set_native_limits(self, low: int, high: int) -> None:
        """Set the software limits (pulses) and enable them; the int32 extremes disable them."""
        (control,) = self._read(reg.PR_CONTROL_SETTING, 1)
        if (low, high) == (reg.INT32_MIN, reg.INT32_MAX):
            self._write(reg.PR_CONTROL_SETTING, [control & ~reg.SOFT_LIMIT_ENABLE & 0xFFFF])
            return
        self._write(reg.SOFT_LIMIT_POS_HIGH, [*split_int32(int(high)), *split_int32(int(low))])
        self._write(reg.PR_CONTROL_SETTING, [control | reg.SOFT_LIMIT_ENABLE])

    def native_range(self, low: float, high: float) -> tuple[int, int]:
        """The pulse limits that keep the axis inside [low, high] (axis units), rounded inward."""
        a, b = sorted(((low - self.offset) / self.scale, (high - self.offset) / self.scale))
        return math.ceil(a - 1e-9), math.floor(b + 1e-9)

    def power_token(self) -> int | None:
        """No volatile register of these drives is known to tell a power cycle: None."""
        return None

    def close(self) -> None:
        pass  # the bus owns the port
