"""Rig configuration: a TOML file naming each device, validated at load.

Every error names the file, the key (``axes.z.travel``) and what was allowed.
Positions are in the axis unit (mm or deg); ``position = native * scale + offset``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from common.errors import ConfigError
from common.table import Table, toml_table

AXIS_NAMES = ("x", "y", "z", "theta")
AXIS_DRIVERS = ("zaber", "pr_drive")
GAUGE_DRIVERS = ("ft300", "m8128", "ati_netft")
CAMERA_DRIVERS = ("v4l2", "folder", "video", "sim")


@dataclass(frozen=True)
class AxisConfig:
    name: str
    driver: str
    port: str
    baudrate: int
    device: int  # Zaber device number, or Modbus device id
    unit: str  # "mm" or "deg"
    travel: tuple[float, float]  # soft limits, unit
    max_speed: float  # unit/s
    jog_speed: float  # unit/s, default for jogs
    offset: float = 0.0  # unit at native zero
    scale: float | None = None  # zaber: unit per microstep (negative flips direction)
    axis_number: int = 1  # zaber: axis of a multi-axis controller
    pulses_per_rev: int | None = None  # pr_drive
    travel_per_rev: float | None = None  # pr_drive: unit per motor revolution
    timeout_s: float = 0.5
    retries: int = 2
    requires_home: bool = True


@dataclass(frozen=True)
class GaugeConfig:
    driver: str
    port: str
    baudrate: int
    device_id: int = 9  # ft300 Modbus id
    mode: str = "stream"  # stream | poll
    rate_hz: int = 100  # m8128 sampling rate
    timeout_s: float = 0.5
    retries: int = 2
    fresh_after_s: float = 0.05  # bound on the stream's measurement-to-arrival latency, s
    rdt_port: int = 49152  # ati_netft: UDP port of RDT (``port`` is the box's host address)
    http_port: int = 80  # ati_netft: where netftapi2.xml (counts per unit) is served
    rdt_mode: str = "realtime"  # ati_netft: realtime | buffered RDT streaming


@dataclass(frozen=True)
class CameraConfig:
    driver: str
    device: str  # /dev/video0, a folder of images, a video file; ignored for sim
    width: int = 640
    height: int = 480
    fps: float = 25.0
    exposure: float | None = None
    white_balance_K: float | None = None
    discard_frames: int = 5
    mm_per_px: float | None = None  # calibration of the frames, stored in every run file


@dataclass(frozen=True)
class SafetyConfig:
    max_force_N: tuple[float, float, float]  # |Fx|, |Fy|, |Fz| limits
    max_torque_Nmm: tuple[float, float, float]  # |Mx|, |My|, |Mz| limits
    poll_s: float = 0.02  # how often a moving rig checks the wrench


@dataclass(frozen=True)
class PendantConfig:
    vendor_id: int | None = None
    product_id: int | None = None
    deadband: float = 0.15


@dataclass(frozen=True)
class RigConfig:
    path: str
    name: str
    axes: dict[str, AxisConfig] = field(default_factory=dict)
    gauge: GaugeConfig | None = None
    camera: CameraConfig | None = None
    safety: SafetyConfig | None = None
    pendant: PendantConfig | None = None


# Physical bounds of a rig config. Each is far outside any sane setting but close enough
# that a typo (or NaN/inf, refused by finite_number) cannot disarm a limit or overflow a
# conversion to native units.
TRAVEL_LIMIT = 1e4  # mm or deg: 10 m of linear travel, or ~28 turns; no lab stage goes further
MAX_SPEED = 1000.0  # mm/s or deg/s: an order of magnitude above motorised lab stages (the simulated ones do 5 mm/s, 30 deg/s)
MAX_TIMEOUT_S = 60.0  # a device that needs longer than a minute to answer is not answering
# The FT300 reports forces as int16 / 100 N and torques as int16 / 1000 N·m (its manual, as
# rig/drivers/ft300.py decodes them), so it saturates at ±327.67 N and ±32 767 N·mm; its rated
# range is ±300 N and ±30 N·m. A limit above the gauge's full scale can never trip (issue 12 saw
# a NaN limit let z press on with the gauge pinned at 327 N); a tactile gel is ruined far below.
MAX_FORCE_LIMIT_N = 300.0
MAX_TORQUE_LIMIT_NMM = 30000.0
MAX_BAUDRATE = 12_000_000  # the fastest USB-serial bridges (FTDI FT232H) top out at 12 Mbaud
MAX_PULSES_PER_REV = 0xFFFF  # the drive holds pulses/rev in one 16-bit register (rig/drivers/pr_registers.py)


def _axis(path: str, name: str, data: Any) -> AxisConfig:
    t = Table(path, f"axes.{name}", data)
    driver = t.get("driver", str, choices=AXIS_DRIVERS)
    unit = t.get("unit", str, "deg" if name == "theta" else "mm", choices=("mm", "deg"))
    travel = t.vector("travel", 2, low=-TRAVEL_LIMIT, high=TRAVEL_LIMIT)
    if travel[0] >= travel[1]:
        raise t.error("travel", f"must be [low, high] with low < high, got {list(travel)}")
    max_speed = t.get("max_speed", float, positive=True, high=MAX_SPEED)
    jog_speed = t.get("jog_speed", float, min(1.0, max_speed), positive=True)
    if jog_speed > max_speed:
        raise t.error("jog_speed", f"must not exceed max_speed ({max_speed}), got {jog_speed}")
    cfg = dict(
        name=name, driver=driver, unit=unit, travel=travel, max_speed=max_speed, jog_speed=jog_speed,
        port=t.get("port", str),
        baudrate=t.get("baudrate", int, 115200 if driver == "zaber" else 38400, positive=True, high=MAX_BAUDRATE),
        device=t.get("device", int, 1, low=0, high=247),
        offset=t.get("offset", float, 0.0, low=-10 * TRAVEL_LIMIT, high=10 * TRAVEL_LIMIT),
        timeout_s=t.get("timeout_s", float, 0.5, positive=True, high=MAX_TIMEOUT_S),
        retries=t.get("retries", int, 2, low=0, high=10),
        requires_home=t.get("requires_home", bool, True),
    )
    if driver == "zaber":
        # unit per microstep: 1e-9 mm is far below any microstep (positions become int
        # microsteps, so a tinier scale overflows them); more than 1000 per step is no stage
        scale = t.get("scale", float, low=-1e3, high=1e3)
        if abs(scale) < 1e-9:
            raise t.error("scale", f"must be non-zero, 1e-9 <= |scale| (unit per microstep; negative flips the "
                                   f"direction), got {scale!r}")
        cfg.update(scale=scale, axis_number=t.get("axis_number", int, 1, low=1, high=9))
    else:
        cfg.update(pulses_per_rev=t.get("pulses_per_rev", int, positive=True, high=MAX_PULSES_PER_REV))
        per_rev = t.get("travel_per_rev", float, low=-TRAVEL_LIMIT, high=TRAVEL_LIMIT)
        if abs(per_rev) < 1e-6:  # below 1 nm (or µdeg) per motor turn no gearbox exists
            raise t.error("travel_per_rev", f"must be non-zero, 1e-6 <= |travel_per_rev| (unit per motor revolution), "
                                            f"got {per_rev!r}")
        cfg.update(travel_per_rev=per_rev)
    t.done()
    return AxisConfig(**cfg)


def _gauge(path: str, data: Any) -> GaugeConfig:
    t = Table(path, "gauge", data)
    driver = t.get("driver", str, choices=GAUGE_DRIVERS)
    cfg = GaugeConfig(
        driver=driver,
        port=t.get("port", str),
        baudrate=t.get("baudrate", int, {"ft300": 19200}.get(driver, 115200), positive=True, high=MAX_BAUDRATE),
        device_id=t.get("device_id", int, 9, low=1, high=247),
        mode=t.get("mode", str, "stream", choices=("stream", "poll")),
        rate_hz=t.get("rate_hz", int, 100, low=1, high=2000),
        timeout_s=t.get("timeout_s", float, 0.5, positive=True, high=MAX_TIMEOUT_S),
        retries=t.get("retries", int, 2, low=0, high=10),
        fresh_after_s=t.get("fresh_after_s", float, 0.05, low=0.0, high=3600.0),
        rdt_port=t.get("rdt_port", int, 49152, low=1, high=65535),
        http_port=t.get("http_port", int, 80, low=1, high=65535),
        rdt_mode=t.get("rdt_mode", str, "realtime", choices=("realtime", "buffered")),
    )
    t.done()
    return cfg


def _camera(path: str, data: Any) -> CameraConfig:
    t = Table(path, "camera", data)
    driver = t.get("driver", str, choices=CAMERA_DRIVERS)
    cfg = CameraConfig(
        driver=driver,
        device=t.get("device", str, "" if driver == "sim" else ...),
        width=t.get("width", int, 640, low=16, high=8192),
        height=t.get("height", int, 480, low=16, high=8192),
        fps=t.get("fps", float, 25.0, positive=True, high=1000.0),  # above any UVC camera
        exposure=t.get("exposure", float, None),  # backend units (negative log2 s on some): finite only
        white_balance_K=t.get("white_balance_K", float, None, low=1000.0, high=15000.0),
        discard_frames=t.get("discard_frames", int, 5, low=0, high=1000),
        mm_per_px=t.get("mm_per_px", float, None, low=1e-4, high=10.0),
    )
    t.done()
    return cfg


def _safety(path: str, data: Any) -> SafetyConfig:
    t = Table(path, "safety", data)
    cfg = SafetyConfig(
        max_force_N=t.vector("max_force_N", 3, positive=True, high=MAX_FORCE_LIMIT_N),
        max_torque_Nmm=t.vector("max_torque_Nmm", 3, positive=True, high=MAX_TORQUE_LIMIT_NMM),
        poll_s=t.get("poll_s", float, 0.02, low=0.001, high=1.0),
    )
    t.done()
    return cfg


def _pendant(path: str, data: Any) -> PendantConfig:
    t = Table(path, "pendant", data)
    cfg = PendantConfig(
        vendor_id=t.get("vendor_id", int, None, low=0, high=0xFFFF),
        product_id=t.get("product_id", int, None, low=0, high=0xFFFF),
        deadband=t.get("deadband", float, 0.15, low=0.0, high=0.9),
    )
    t.done()
    return cfg


def parse_config(text: str, path: str = "<string>") -> RigConfig:
    top, data = toml_table(text, path)
    rig = Table(path, "rig", top.get("rig", dict, {}))
    name = rig.get("name", str, Path(path).stem)
    rig.done()
    axes_table = Table(path, "axes", top.get("axes", dict, {}))
    axes = {}
    for axis_name in axes_table.data:
        if axis_name not in AXIS_NAMES:
            raise axes_table.error(axis_name, f"unknown axis; expected one of {', '.join(AXIS_NAMES)}")
        axes[axis_name] = _axis(path, axis_name, axes_table.get(axis_name, dict))
    gauge = _gauge(path, top.get("gauge", dict)) if "gauge" in data else None
    camera = _camera(path, top.get("camera", dict)) if "camera" in data else None
    safety = _safety(path, top.get("safety", dict)) if "safety" in data else None
    pendant = _pendant(path, top.get("pendant", dict)) if "pendant" in data else None
    top.done()
    if axes and safety is None:
        raise ConfigError(path, "safety", "is required when axes are configured: no stage moves without force limits "
                                          "(max_force_N = [Fx, Fy, Fz], max_torque_Nmm = [Mx, My, Mz])")
    if axes and gauge is None:
        raise ConfigError(path, "gauge", "is required when axes are configured: force limits need a force gauge")
    _check_ports(path, axes, gauge)
    return RigConfig(path=path, name=name, axes=axes, gauge=gauge, camera=camera, safety=safety, pendant=pendant)


def _check_ports(path: str, axes: dict[str, AxisConfig], gauge: GaugeConfig | None) -> None:
    by_port: dict[str, AxisConfig] = {}
    for a in axes.values():
        other = by_port.setdefault(a.port, a)
        if other is not a and (other.driver, other.baudrate) != (a.driver, a.baudrate):
            raise ConfigError(path, f"axes.{a.name}.port",
                              f"{a.port} is shared with axis {other.name} ({other.driver} @ {other.baudrate} baud) "
                              f"but this axis is {a.driver} @ {a.baudrate} baud")
        if other is not a and a.device == other.device and a.axis_number == other.axis_number:
            raise ConfigError(path, f"axes.{a.name}.device", f"device {a.device} on {a.port} is already axis {other.name}")
    if gauge is not None and gauge.port in by_port:
        raise ConfigError(path, "gauge.port", f"{gauge.port} is also used by axis {by_port[gauge.port].name}; "
                                              "the gauge needs its own port (its stream mode owns the line)")


def load_config(path: str | Path) -> RigConfig:
    p = Path(path)
    try:
        text = p.read_text()
    except FileNotFoundError as exc:
        raise ConfigError(str(p), "-", "file not found") from exc
    except OSError as exc:
        raise ConfigError(str(p), "-", f"cannot read: {exc}") from exc
    return parse_config(text, str(p))
