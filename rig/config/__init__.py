"""Rig configuration: a TOML file naming each device, validated at load.

Every error names the file, the key (``axes.z.travel``) and what was allowed.
Positions are in the axis unit (mm or deg); ``position = native * scale + offset``.
The device kinds, their own keys and default wire settings come from the registry
(``rig/config/registry.py``); this module reads the keys every device of a role has.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from common.errors import ConfigError
from common.gauge_range import MAX_FORCE_LIMIT_N, MAX_TORQUE_LIMIT_NMM  # noqa: F401 (re-exported: the CLI's bounds)
from common.table import Table, toml_table
from rig.config.registry import (  # noqa: F401
    MAX_BAUDRATE,
    MAX_PULSES_PER_REV,
    MAX_TIMEOUT_S,
    TRAVEL_LIMIT,
    DeviceKind,
    Key,
    kind,
    kinds,
)
from rig.config.safety import (  # noqa: F401 (moved to rig/config/safety.py; imported from here)
    DEFAULT_MAX_DEPTH_FRACTION,
    DEFAULT_WINDOW_STIFFNESS_N_PER_MM,
    PendantConfig,
    SafetyConfig,
    deepest_fraction,
    parse_pendant,
    parse_safety,
    surface_tolerance_mm,
)

AXIS_NAMES = ("x", "y", "z", "theta")

# An axis's stop: the device's reaction to the stop command (the wire and the host are measured
# when the rig opens) and its deceleration. Conservative where a config does not say.
DEFAULT_STOP_LATENCY_S = 0.01
DEFAULT_STOP_DECEL = 20.0  # mm/s² (deg/s² for a rotary axis)


class KindKeys:
    """A device config whose kind-specific keys (``options``, from its registry row) read
    as attributes too: ``cfg.device_id`` on an FT300, ``cfg.scale`` on a Zaber axis."""

    def __getattr__(self, name: str) -> Any:
        options = self.__dict__.get("options") or {}
        if name in options:
            return options[name]
        raise AttributeError(f"{type(self).__name__} (driver {self.__dict__.get('driver')!r}) has no key {name!r}")


@dataclass(frozen=True)
class AxisConfig(KindKeys):
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
    timeout_s: float = 0.5
    retries: int = 2
    requires_home: bool = True
    stop_latency_s: float = DEFAULT_STOP_LATENCY_S  # the device's reaction to a stop command
    stop_decel: float = DEFAULT_STOP_DECEL  # unit/s²: how fast a stop brings the axis to rest
    # the kind's own keys (registry row): zaber scale, axis_number; pr_drive pulses_per_rev, travel_per_rev
    options: Mapping[str, Any] = field(default_factory=dict, hash=False)


@dataclass(frozen=True)
class GaugeConfig(KindKeys):
    driver: str
    port: str  # a serial port URL, or a host address for network gauges
    baudrate: int | None  # None: not a serial gauge (registry row's wire.baudrate)
    mode: str = "stream"  # stream | poll
    timeout_s: float = 0.5
    retries: int = 2
    fresh_after_s: float = 0.05  # bound on the stream's measurement-to-arrival latency, s
    # the kind's own keys (registry row): ft300 device_id; m8128 rate_hz; ati_netft rdt_port, http_port, rdt_mode
    options: Mapping[str, Any] = field(default_factory=dict, hash=False)


@dataclass(frozen=True)
class CameraConfig(KindKeys):
    driver: str
    device: str  # /dev/video0, a folder of images, a video file; "" for sim
    width: int = 640
    height: int = 480
    fps: float = 25.0
    exposure: float | None = None
    white_balance_K: float | None = None
    discard_frames: int = 5
    mm_per_px: float | None = None  # calibration of the frames, stored in every run file
    options: Mapping[str, Any] = field(default_factory=dict, hash=False)  # the kind's own keys besides device
    sensor_profile: str | None = None  # the sensor profile (TOML) the frames come from, recorded in every run file


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
# conversion to native units. TRAVEL_LIMIT, MAX_TIMEOUT_S, MAX_BAUDRATE and
# MAX_PULSES_PER_REV live in the registry, whose rows use them.
MAX_SPEED = (
    1000.0  # mm/s or deg/s: an order of magnitude above motorised lab stages (the simulated ones do 5 mm/s, 30 deg/s)
)
# MAX_FORCE_LIMIT_N, MAX_TORQUE_LIMIT_NMM (imported above): a limit above the gauge's full scale
# can never trip, common/gauge_range.py says why these.


def _driver(t: Table, role: str) -> DeviceKind:
    return kind(role, t.get("driver", str, choices=kinds(role)), path=t.path, key=t.key("driver"))


def _kind_keys(t: Table, keys: tuple[Key, ...]) -> dict[str, Any]:
    """The values of a registry row's own keys, each checked like every other key."""
    values = {}
    for k in keys:
        value = t.get(k.name, k.kind, k.default, choices=k.choices, low=k.low, high=k.high, positive=k.positive)
        if k.min_abs is not None and value is not None and abs(value) < k.min_abs:
            why = f" ({k.doc})" if k.doc else ""
            raise t.error(k.name, f"must be non-zero, {k.min_abs:g} <= |{k.name}|{why}, got {value!r}")
        values[k.name] = value
    return values


def _wire(t: Table, row: DeviceKind) -> dict[str, Any]:
    """baudrate (serial kinds only), timeout_s and retries, defaulting to the row's wire settings."""
    wire = dict(
        timeout_s=t.get("timeout_s", float, row.wire.timeout_s, positive=True, high=MAX_TIMEOUT_S),
        retries=t.get("retries", int, row.wire.retries, low=0, high=10),
    )
    if row.wire.baudrate is not None:
        wire["baudrate"] = t.get("baudrate", int, row.wire.baudrate, positive=True, high=MAX_BAUDRATE)
    return wire


def _axis(path: str, name: str, data: Any) -> AxisConfig:
    t = Table(path, f"axes.{name}", data)
    row = _driver(t, "axis")
    unit = t.get("unit", str, "deg" if name == "theta" else "mm", choices=("mm", "deg"))
    travel = t.vector("travel", 2, low=-TRAVEL_LIMIT, high=TRAVEL_LIMIT)
    if travel[0] >= travel[1]:
        raise t.error("travel", f"must be [low, high] with low < high, got {list(travel)}")
    max_speed = t.get("max_speed", float, positive=True, high=MAX_SPEED)
    jog_speed = t.get("jog_speed", float, min(1.0, max_speed), positive=True)
    if jog_speed > max_speed:
        raise t.error("jog_speed", f"must not exceed max_speed ({max_speed}), got {jog_speed}")
    cfg = AxisConfig(
        name=name,
        driver=row.name,
        unit=unit,
        travel=(travel[0], travel[1]),
        max_speed=max_speed,
        jog_speed=jog_speed,
        port=t.get("port", str),
        device=t.get("device", int, 1, low=0, high=247),
        offset=t.get("offset", float, 0.0, low=-10 * TRAVEL_LIMIT, high=10 * TRAVEL_LIMIT),
        requires_home=t.get("requires_home", bool, True),
        stop_latency_s=t.get("stop_latency_s", float, DEFAULT_STOP_LATENCY_S, low=0.0, high=MAX_TIMEOUT_S),
        stop_decel=t.get("stop_decel", float, DEFAULT_STOP_DECEL, positive=True, high=1e6),
        options=_kind_keys(t, row.keys),
        **_wire(t, row),
    )
    t.done()
    return cfg


def _gauge(path: str, data: Any) -> GaugeConfig:
    t = Table(path, "gauge", data)
    row = _driver(t, "gauge")
    wire = _wire(t, row)
    cfg = GaugeConfig(
        driver=row.name,
        port=t.get("port", str),
        baudrate=wire.pop("baudrate", None),
        mode=t.get("mode", str, "stream", choices=("stream", "poll")),
        fresh_after_s=t.get("fresh_after_s", float, 0.05, low=0.0, high=3600.0),
        options=_kind_keys(t, row.keys),
        **wire,
    )
    t.done()
    return cfg


def _camera(path: str, data: Any) -> CameraConfig:
    t = Table(path, "camera", data)
    row = _driver(t, "camera")
    options = _kind_keys(t, row.keys)
    cfg = CameraConfig(
        driver=row.name,
        device=options.pop("device", ""),
        width=t.get("width", int, 640, low=16, high=8192),
        height=t.get("height", int, 480, low=16, high=8192),
        fps=t.get("fps", float, 25.0, positive=True, high=1000.0),  # above any UVC camera
        exposure=t.get("exposure", float, None),  # backend units (negative log2 s on some): finite only
        white_balance_K=t.get("white_balance_K", float, None, low=1000.0, high=15000.0),
        discard_frames=t.get("discard_frames", int, 5, low=0, high=1000),
        mm_per_px=t.get("mm_per_px", float, None, low=1e-4, high=10.0),
        options=options,
        sensor_profile=_relative_path(path, t.get("sensor_profile", str, None)),
    )
    t.done()
    return cfg


def _relative_path(config_path: str, value: str | None) -> str | None:
    """A path a config names, relative to the config's folder (absolute paths as given)."""
    if value is None or Path(value).is_absolute() or config_path.startswith("<"):
        return value
    return str(Path(config_path).parent / value)


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
    safety = parse_safety(path, top.get("safety", dict)) if "safety" in data else None
    pendant = parse_pendant(path, top.get("pendant", dict)) if "pendant" in data else None
    top.done()
    if axes and safety is None:
        raise ConfigError(
            path,
            "safety",
            "is required when axes are configured: no stage moves without force limits "
            "(max_force_N = [Fx, Fy, Fz], max_torque_Nmm = [Mx, My, Mz])",
        )
    if axes and gauge is None:
        raise ConfigError(path, "gauge", "is required when axes are configured: force limits need a force gauge")
    if "z" in axes and safety is not None and safety.gel_thickness_mm is None:
        raise ConfigError(
            path,
            "safety.gel_thickness_mm",
            "is required when a z axis is configured: the depth guard keeps the indenter off the window "
            "behind the gel (your sensor profile's [gel] thickness_mm, in mm)",
        )
    _check_ports(path, axes, gauge)
    return RigConfig(path=path, name=name, axes=axes, gauge=gauge, camera=camera, safety=safety, pendant=pendant)


def _check_ports(path: str, axes: dict[str, AxisConfig], gauge: GaugeConfig | None) -> None:
    by_port: dict[str, AxisConfig] = {}
    for a in axes.values():
        other = by_port.setdefault(a.port, a)
        if other is not a and (other.driver, other.baudrate) != (a.driver, a.baudrate):
            raise ConfigError(
                path,
                f"axes.{a.name}.port",
                f"{a.port} is shared with axis {other.name} ({other.driver} @ {other.baudrate} baud) "
                f"but this axis is {a.driver} @ {a.baudrate} baud",
            )
        if other is not a and (a.device, a.options.get("axis_number")) == (
            other.device,
            other.options.get("axis_number"),
        ):
            raise ConfigError(
                path, f"axes.{a.name}.device", f"device {a.device} on {a.port} is already axis {other.name}"
            )
    if gauge is not None and gauge.port in by_port:
        raise ConfigError(
            path,
            "gauge.port",
            f"{gauge.port} is also used by axis {by_port[gauge.port].name}; "
            "the gauge needs its own port (its stream mode owns the line)",
        )


def load_config(path: str | Path) -> RigConfig:
    p = Path(path)
    try:
        text = p.read_text()
    except FileNotFoundError as exc:
        raise ConfigError(str(p), "-", "file not found") from exc
    except UnicodeDecodeError as exc:
        raise ConfigError(
            str(p), "-", f"not a rig config: byte {exc.start} is not UTF-8 text (a rig config is a TOML text file)"
        ) from None
    except OSError as exc:
        raise ConfigError(str(p), "-", f"cannot read: {exc}") from exc
    return parse_config(text, str(p))
