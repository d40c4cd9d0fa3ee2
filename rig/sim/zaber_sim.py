"""A Zaber ASCII daisy chain: one or more single-axis integrated devices on one port.

Speaks the bytes of the real protocol (Zaber ASCII protocol manual, "Command
Format", "Reply Format", "Message IDs", "Checksums", "Warning Flags", "Settings")
and moves the world's stages. Each device answers the identification zaber-motion
sends (deviceid, system.serial, version, version.build, comm.packet.size.max,
system.axiscount, resolution) so Zaber's own library identifies it as the product
it models (an X-LSM025A by default: docs/hardware.md, "Zaber"). A command with a
bad checksum is ignored, so the host sees a timeout and retries.
"""

from __future__ import annotations

from dataclasses import dataclass

from rig.drivers import zaber_ascii as za
from rig.sim.link import RequestReplyDevice
from rig.sim.stage import SimStage, StageFault

# X-LSM025A: device id from Zaber's id map (zaber.com/id-mapping), 0.047625 µm
# microstep at the default resolution of 64 (zaber.com/manuals/X-LSM, specifications).
X_LSM025A_DEVICE_ID = 50030
# Native acceleration: 1 data unit = 10000 / 1.6384 microsteps/s² (manual, "accel").
ACCEL_UNITS_PER_USTEP_S2 = 1.6384 / 10000
# Stopping (docs/simulator.md, "Stopping"). `stop` decelerates to rest at the device's
# deceleration, and `set accel` sets the acceleration and the deceleration together: Zaber's
# Stop command page (zaber.com/wiki/T-Series/Commands/Stop) and "Stop Behaviour" (A-Series:
# the rate is Set Acceleration's, or Set Deceleration Only's), whose ASCII settings are
# accel, motion.accelonly and motion.decelonly (ASCII manual, "Settings"). A second stop
# while decelerating stops at once there; not modelled. `estop` stops without the
# deceleration setting, yet a motor has a limit. ASSUMED (not in the pages at hand): the
# largest ramp a 16-bit accel setting holds, 32767 units (9.5 m/s² at 0.047625 µm), 160x
# the default 205 (59.6 mm/s²).
ESTOP_ACCEL_NATIVE = 32767
# From a command's last byte to the device acting on it: an integrated controller answers
# within about 1 ms. ASSUMED (the figure this project works with; no manual gives one).
REACTION_S = 0.001
# Settings that belong to the device, not to an axis: asking them of axis 1 is
# rejected DEVICEONLY (manual, "Reply Format", rejection reasons).
USER_VDATA = tuple(f"user.vdata.{i}" for i in range(4))  # FW 7.23+: device-scope integers (see below)
DEVICE_SETTINGS = (
    "deviceid",
    "system.serial",
    "version",
    "version.build",
    "comm.packet.size.max",
    "system.axiscount",
    *USER_VDATA,
)
# Travel limits (ASCII settings limit.min / limit.max, native microsteps; Zaber's Set Minimum /
# Maximum Position pages for FW6, whose rules these are): a move abs or rel whose target lies
# outside them is rejected BADDATA; a velocity move stops at them; `move min` / `move max` go to
# them. A limit that leaves the carriage outside is accepted; a move back to a target inside is
# then the only one taken. They are kept over a power cycle (the device stores them). ASSUMED (no
# page at hand says): a move under way whose target a new limit excludes is cut short at it,
# as a velocity move is.
# user.vdata.0-3 (FW 7.23+, device scope, 64-bit): ASSUMED volatile, 0 at power-up, as Zaber's
# own example uses them for temporary storage; the rig writes a token there to tell a power cycle.


@dataclass
class ZaberDeviceSim:
    stage: SimStage
    microstep: float  # stage units (mm or deg) per microstep
    maxspeed: int = 153600  # native velocity units (manual default for X-series stages)
    accel: int = 205  # motion.accelonly, native units (the X-LSM default); `set accel` sets decel too
    decel: int = 205  # motion.decelonly: a move's slowing down and the `stop` ramp
    device_id: int = X_LSM025A_DEVICE_ID
    serial: int = 0  # 0: the chain gives each device a distinct one
    version: str = "7.33"
    build: int = 16000  # assumed: any build identifies; tests/data's store names it
    resolution: int = 64
    packet_size_max: int = 80  # longest command line accepted (manual, comm.packet.size.max)
    pos_offset: float = 0.0  # stage position at native 0; `set pos` moves it, homing clears it
    limit_min: int | None = None  # limit.min, native; None: the travel's own end
    limit_max: int | None = None
    vdata: list[int] | None = None  # user.vdata.0-3, volatile

    def __post_init__(self):
        self.apply_ramps()
        if self.vdata is None:
            self.vdata = [0, 0, 0, 0]

    def power_cycle(self) -> None:
        """Fault injection: the controller loses power and comes back (volatile settings cleared,
        the stored ones kept, the position no longer referenced)."""
        self.vdata = [0, 0, 0, 0]
        self.stage.homed = False

    def native_limits(self) -> tuple[int, int]:
        """(limit.min, limit.max) in native microsteps: as set, else the stage's travel."""
        ends = sorted((self.to_native(self.stage.spec.travel[0]), self.to_native(self.stage.spec.travel[1])))
        return (
            ends[0] if self.limit_min is None else self.limit_min,
            ends[1] if self.limit_max is None else self.limit_max,
        )

    def stage_range(self) -> tuple[float, float]:
        """The limits as stage positions, inside the travel."""
        lo, hi = self.native_limits()
        a, b = sorted((self.pos_offset + lo * self.microstep, self.pos_offset + hi * self.microstep))
        travel = self.stage.spec.travel
        return max(a, travel[0]), min(b, travel[1])

    # native units, in one place
    def to_native(self, position: float) -> int:
        return round((position - self.pos_offset) / self.microstep)

    def speed(self, native_velocity: int) -> float:
        return abs(native_velocity) / za.VELOCITY_UNITS_PER_USTEP_S * self.microstep

    def acceleration(self, native_accel: int) -> float:
        """Stage units/s² of a native acceleration (205 → 59.6 mm/s² at 0.047625 µm)."""
        return native_accel / ACCEL_UNITS_PER_USTEP_S2 * self.microstep

    def apply_ramps(self) -> None:
        """The stage moves and stops as this device's settings say."""
        decel = self.acceleration(self.decel)
        self.stage.configure(
            accel=self.acceleration(self.accel),
            decel=decel,
            stop_decel=decel,
            stop_reaction_s=REACTION_S,
            abrupt_decel=max(decel, self.acceleration(ESTOP_ACCEL_NATIVE)),
        )


class ZaberChainSim(RequestReplyDevice):
    serves_inline = True  # pure computation on the simulated stages (rig/sim/link.py: SimServer.inline)

    def __init__(self, clock, devices: dict[int, ZaberDeviceSim]):
        self.clock = clock
        self.devices = dict(sorted(devices.items()))  # broadcast replies come in address order
        for number, dev in self.devices.items():
            if dev.serial == 0:
                dev.serial = 33000 + number
        self._buf = b""

    def feed(self, data: bytes, now_s: float) -> list[bytes]:
        self._buf += data
        out = []
        while b"\n" in self._buf:
            line, self._buf = self._buf.split(b"\n", 1)
            out.extend(self._handle(line.strip(b"\r"), now_s))
        return out

    # -- one command line -------------------------------------------------------
    def _handle(self, line: bytes, now_s: float) -> list[bytes]:
        try:
            text = line.decode("ascii")
        except UnicodeDecodeError:
            return []
        if not text.startswith("/"):
            return []
        body = text[1:]
        with_checksum = False
        if ":" in body:
            body, given = body.rsplit(":", 1)
            if za.checksum(body) != given.strip().upper():
                return []
            with_checksum = True
        device, axis, msg_id, words = parse_command(body)
        if device == 0:
            targets = self.devices
        else:
            targets = {device: self.devices[device]} if device in self.devices else {}
        return [self._reply(number, dev, axis, msg_id, words, now_s, with_checksum) for number, dev in targets.items()]

    def _flags(self, dev: ZaberDeviceSim) -> list[str]:
        flags = []
        if dev.stage.stalled:
            flags.append("FS")
        if not dev.stage.homed:
            flags.append("WR")
        return flags

    def _reply(
        self, number: int, dev: ZaberDeviceSim, axis: int, msg_id, words: list[str], now_s: float, with_checksum: bool
    ) -> bytes:
        with dev.stage.lock:
            ok, data = self._execute(dev, axis, words, now_s)
            status = "BUSY" if dev.stage.busy(now_s) else "IDLE"
            flags = self._flags(dev)
        body = f"{number:02d} {axis}"
        if msg_id is not None:
            body += f" {msg_id:02d}"
        body += f" {'OK' if ok else 'RJ'} {status} {flags[0] if flags else '--'} {data}"
        if with_checksum:
            body += ":" + za.checksum(body)
        return f"@{body}\r\n".encode("ascii")

    def _execute(self, dev: ZaberDeviceSim, axis: int, words: list[str], now_s: float) -> tuple[bool, str]:
        if axis not in (0, 1):
            return False, "BADAXIS"
        if not words:
            return True, "0"
        if words[0] == "get" and len(words) == 2:
            return self._get(dev, axis, words[1], now_s)
        if words[0] == "set" and len(words) == 3:
            return self._set(dev, axis, words[1], words[2], now_s)
        if words[0] == "warnings" and len(words) <= 2:
            flags = self._flags(dev)
            if words[1:] == ["clear"]:
                dev.stage.clear_stall()
            elif words[1:]:
                return False, "BADCOMMAND"
            return True, " ".join([f"{len(flags):02d}", *flags])
        if words in (["stop"], ["estop"]):
            dev.stage.stop(now_s, abrupt=words == ["estop"])
            return True, "0"
        if words == ["home"]:
            dev.pos_offset = 0.0  # the home switch is native 0
            dev.stage.home(now_s)
            return True, "0"
        if words[0] == "move":
            return self._move(dev, words[1:], now_s)
        return False, "BADCOMMAND"

    def _get(self, dev: ZaberDeviceSim, axis: int, name: str, now_s: float) -> tuple[bool, str]:
        if name in DEVICE_SETTINGS and axis != 0:
            return False, "DEVICEONLY"
        lo, hi = dev.native_limits()
        values = {
            "deviceid": dev.device_id,
            "system.serial": dev.serial,
            "version": dev.version,
            "version.build": dev.build,
            "comm.packet.size.max": dev.packet_size_max,
            "system.axiscount": 1,
            "resolution": dev.resolution,
            "pos": dev.to_native(dev.stage.position(now_s)),
            "maxspeed": dev.maxspeed,
            "accel": dev.accel,  # ASSUMED: accel reads back motion.accelonly
            "motion.accelonly": dev.accel,
            "motion.decelonly": dev.decel,
            "limit.min": lo,
            "limit.max": hi,
            **dict(zip(USER_VDATA, dev.vdata or [0, 0, 0, 0])),
        }
        if name not in values:
            # Also what an integrated device answers for peripheralid / peripheral.id
            # (no peripheral) and what older firmware answers for newer settings.
            return False, "BADCOMMAND"
        return True, str(values[name])

    def _set(self, dev: ZaberDeviceSim, axis: int, name: str, text: str, now_s: float) -> tuple[bool, str]:
        settable = ("maxspeed", "accel", "motion.accelonly", "motion.decelonly", "pos", "limit.min", "limit.max")
        if name not in settable and name not in USER_VDATA:
            return False, "BADCOMMAND"
        if name in USER_VDATA and axis != 0:
            return False, "DEVICEONLY"
        try:
            value = int(text)
        except ValueError:
            return False, "BADDATA"
        if name in USER_VDATA:
            if not -(2**63) <= value < 2**63:
                return False, "BADDATA"
            assert dev.vdata is not None
            dev.vdata[USER_VDATA.index(name)] = value
            return True, "0"
        if name in ("limit.min", "limit.max"):
            if not -1_000_000_000 <= value <= 1_000_000_000:
                return False, "BADDATA"
            setattr(dev, name.replace(".", "_"), value)
            self._keep_inside(dev, now_s)
            return True, "0"
        if name == "pos":
            # Re-reference without moving: the carriage stays, its number changes.
            dev.pos_offset = dev.stage.position(now_s) - value * dev.microstep
            return True, "0"
        if value <= 0:
            return False, "BADDATA"
        if name == "maxspeed":
            dev.maxspeed = value
            return True, "0"
        if name in ("accel", "motion.accelonly"):
            dev.accel = value
        if name in ("accel", "motion.decelonly"):
            dev.decel = value
        dev.apply_ramps()
        return True, "0"

    def _keep_inside(self, dev: ZaberDeviceSim, now_s: float) -> None:
        """A move under way whose target a new limit excludes stops at the limit (ASSUMED)."""
        stage = dev.stage
        if not stage.busy(now_s):
            return
        lo, hi = dev.stage_range()
        target = stage.target
        if target is None or lo - 1e-12 <= target <= hi + 1e-12:
            return
        here = stage.position(now_s)
        edge = lo if target < lo else hi
        if (edge - here) * (target - here) > 0:  # still between here and the target: stop there
            stage.move_to(edge, stage.commanded_speed or stage.spec.max_speed, now_s)

    def _move(self, dev: ZaberDeviceSim, args: list[str], now_s: float) -> tuple[bool, str]:
        lo, hi = dev.stage_range()
        if args in (["min"], ["max"]):
            target, speed = (lo if args == ["min"] else hi), dev.speed(dev.maxspeed)
        elif len(args) == 2 and args[0] in ("abs", "rel", "vel"):
            try:
                value = int(args[1])
            except ValueError:
                return False, "BADDATA"
            if args[0] == "vel":
                if value == 0:
                    dev.stage.stop(now_s)
                    return True, "0"
                here = dev.stage.position(now_s)
                if (value > 0 and here >= hi - 1e-12) or (value < 0 and here <= lo + 1e-12):
                    return False, "BADDATA"  # at or past the limit it would run into (ASSUMED reply)
                # A velocity move runs until stopped or until the travel limit.
                target, speed = (hi if value > 0 else lo), dev.speed(value)
            else:
                start = dev.stage.position(now_s) if args[0] == "rel" else dev.pos_offset
                target = start + value * dev.microstep
                speed = dev.speed(dev.maxspeed)
        else:
            return False, "BADCOMMAND"
        if not lo - 1e-12 <= target <= hi + 1e-12:
            return False, "BADDATA"  # a target outside the limits (a carriage outside comes back by one inside)
        try:
            dev.stage.move_to(target, speed, now_s)
        except StageFault:
            return False, "BADDATA"
        return True, "0"


def parse_command(body: str) -> tuple[int, int, int | None, list[str]]:
    """``[device] [axis] [id] words`` → (device, axis, message id, words).

    Device and axis are optional (manual, "Command Format"): a command with neither
    goes to every device (``/get pos``); a message id needs both before it.
    """
    words = body.split()
    device = axis = 0
    msg_id = None
    if words and words[0].isdigit():
        device, words = int(words[0]), words[1:]
        if words and words[0].isdigit():
            axis, words = int(words[0]), words[1:]
            if words and words[0].isdigit() and len(words[0]) <= 2:
                msg_id, words = int(words[0]), words[1:]
    return device, axis, msg_id, words
