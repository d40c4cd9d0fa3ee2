"""A Zaber ASCII daisy chain: one or more single-axis devices on one port.

Speaks the bytes of the real protocol (message ids, optional checksums, warning
flags, rejections) and moves the world's stages. A command with a bad checksum is
ignored, so the host sees a timeout and retries.
"""

from __future__ import annotations

from rig.sim.link import RequestReplyDevice

from dataclasses import dataclass

from rig.drivers import zaber_ascii as za
from rig.sim.stage import SimStage, StageFault


@dataclass
class ZaberDeviceSim:
    stage: SimStage
    microstep: float  # stage units (mm or deg) per microstep
    maxspeed: int = 153600  # native velocity units
    accel: int = 205  # native acceleration units (informational)
    cleared_warnings: bool = False


class ZaberChainSim(RequestReplyDevice):
    def __init__(self, clock, devices: dict[int, ZaberDeviceSim]):
        self.clock = clock
        self.devices = devices
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
            if za.checksum(body) != given.upper():
                return []
            with_checksum = True
        words = body.split()
        device = int(words[0]) if words and words[0].isdigit() else 0
        axis = int(words[1]) if len(words) > 1 and words[1].isdigit() else 0
        rest = words[2:] if len(words) > 1 and words[1].isdigit() else words[1:]
        msg_id = None
        if rest and rest[0].isdigit() and len(rest[0]) <= 2:
            msg_id = int(rest[0])
            rest = rest[1:]
        targets = self.devices if device == 0 else ({device: self.devices[device]} if device in self.devices else {})
        replies = []
        for number, dev in targets.items():
            replies.append(self._reply(number, dev, axis, msg_id, rest, now_s, with_checksum))
        return replies

    def _flag(self, dev: ZaberDeviceSim) -> str:
        flags = self._flags(dev)
        return flags[0] if flags else "--"

    def _flags(self, dev: ZaberDeviceSim) -> list[str]:
        flags = []
        if dev.stage.stalled:
            flags.append("FS")
        if not dev.stage.homed:
            flags.append("WR")
        return flags

    def _reply(self, number: int, dev: ZaberDeviceSim, axis: int, msg_id, words: list[str], now_s: float,
               with_checksum: bool) -> bytes:
        ok, data = self._execute(dev, axis, words, now_s)
        status = "BUSY" if dev.stage.busy(now_s) else "IDLE"
        body = f"{number:02d} {axis}"
        if msg_id is not None:
            body += f" {msg_id:02d}"
        body += f" {'OK' if ok else 'RJ'} {status} {self._flag(dev)} {data}"
        if with_checksum:
            body += ":" + za.checksum(body)
        return f"@{body}\r\n".encode("ascii")

    def _execute(self, dev: ZaberDeviceSim, axis: int, words: list[str], now_s: float) -> tuple[bool, str]:
        stage = dev.stage
        if axis not in (0, 1):
            return False, "BADAXIS"
        cmd = " ".join(words)
        if cmd == "":
            return True, "0"
        if cmd == "get pos":
            return True, str(round(stage.position(now_s) / dev.microstep))
        if cmd == "get maxspeed":
            return True, str(dev.maxspeed)
        if cmd == "warnings":
            flags = self._flags(dev)
            return True, " ".join([f"{len(flags):02d}", *flags])
        if cmd == "warnings clear":
            flags = self._flags(dev)
            stage.clear_stall()
            return True, " ".join([f"{len(flags):02d}", *flags])
        if cmd in ("stop", "estop"):
            stage.stop(now_s)
            return True, "0"
        if cmd == "home":
            stage.home(now_s)
            return True, "0"
        if len(words) == 3 and words[0] == "set" and words[1] in ("maxspeed", "accel"):
            try:
                value = int(words[2])
            except ValueError:
                return False, "BADDATA"
            if value <= 0:
                return False, "BADDATA"
            setattr(dev, words[1], value)
            return True, "0"
        if len(words) == 3 and words[0] == "move" and words[1] in ("abs", "rel"):
            try:
                value = int(words[2])
            except ValueError:
                return False, "BADDATA"
            target = value * dev.microstep
            if words[1] == "rel":
                target += stage.position(now_s)
            speed = dev.maxspeed / za.VELOCITY_UNITS_PER_USTEP_S * dev.microstep
            try:
                stage.move_to(target, speed, now_s)
            except StageFault:
                return False, "BADDATA"
            return True, "0"
        return False, "BADCOMMAND"
