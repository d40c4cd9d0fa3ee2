"""3Dconnexion SpaceMouse (or a similar six-axis HID pendant) as a jog input, via hidapi.

Reports: id 1 translation (x, y, z int16 LE; 13-byte variants append rotation),
id 2 rotation (rx, ry, rz int16 LE), id 3 buttons (bitmask, LE). Values span about
±350.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, replace

VENDOR_IDS = (0x256F, 0x046D)  # 3Dconnexion, and Logitech for older SpaceNavigators
FULL_SCALE = 350.0


@dataclass(frozen=True)
class PendantState:
    translation: tuple[int, int, int] = (0, 0, 0)
    rotation: tuple[int, int, int] = (0, 0, 0)
    buttons: int = 0


class ReportError(ValueError):
    pass


def parse_report(report: bytes, state: PendantState) -> PendantState:
    """The state after one input report. Raises ReportError on a malformed report."""
    if not report:
        raise ReportError("empty HID report")
    rid, body = report[0], bytes(report[1:])
    if rid == 1:
        if len(body) >= 12:
            v = struct.unpack("<6h", body[:12])
            return replace(state, translation=v[:3], rotation=v[3:])
        if len(body) >= 6:
            return replace(state, translation=struct.unpack("<3h", body[:6]))
        raise ReportError(f"translation report too short: {report.hex()}")
    if rid == 2:
        if len(body) < 6:
            raise ReportError(f"rotation report too short: {report.hex()}")
        return replace(state, rotation=struct.unpack("<3h", body[:6]))
    if rid == 3:
        return replace(state, buttons=int.from_bytes(body, "little"))
    return state  # battery, LED and other reports carry no motion


AXIS_CHANNELS = {"x": ("translation", 0), "y": ("translation", 1), "z": ("translation", 2), "theta": ("rotation", 2)}


def deflection(state: PendantState, axis: str, deadband: float = 0.15) -> float:
    """Pendant deflection for a rig axis, in [-1, 1], zero inside the dead band.

    z is reported positive when the cap is pushed down; the rig's z is positive up.
    """
    kind, i = AXIS_CHANNELS[axis]
    raw = getattr(state, kind)[i] / FULL_SCALE
    if axis == "z":
        raw = -raw
    raw = max(-1.0, min(1.0, raw))
    return 0.0 if abs(raw) < deadband else raw


class SpaceMouse:
    """Reads reports from an hidapi-like device (``read(size, timeout_ms) -> list[int]``)."""

    def __init__(self, device, name: str = "pendant"):
        self.device = device
        self.name = name
        self.state = PendantState()

    def poll(self, timeout_ms: int = 20) -> PendantState:
        """Apply every report waiting (up to ``timeout_ms`` for the first) and return the state."""
        data = self.device.read(64, timeout_ms)
        while data:
            self.state = parse_report(bytes(data), self.state)
            data = self.device.read(64, 0)
        return self.state

    def close(self) -> None:
        self.device.close()


def open_spacemouse(vendor_id: int | None = None, product_id: int | None = None) -> SpaceMouse:
    """Open the first matching HID pendant through hidapi (the thin real-device path)."""
    import hid

    for info in hid.enumerate():
        if (vendor_id is None and info["vendor_id"] in VENDOR_IDS) or info["vendor_id"] == vendor_id:
            if product_id is None or info["product_id"] == product_id:
                dev = hid.device()
                dev.open_path(info["path"])
                return SpaceMouse(dev, name=f"pendant {info.get('product_string') or hex(info['product_id'])}")
    raise LookupError("no SpaceMouse-like HID device found (check the USB cable and the udev rule for hidraw)")
