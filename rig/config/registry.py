"""The device registry: one row per device kind, from which everything else derives.

A row names a kind's role (axis, gauge, camera), the config keys of its own (checked
by ``rig.config`` like every key: type, default, bounds), its default wire settings,
its opener and its simulator. Config validation, the factory (``rig/factory.py``), the
simulated rig (``rig/sim/rig_sim.py``), ``rig status`` and the command line's choices
read this table; none of them lists device kinds of its own.

Pure data at the bottom of the rig: the opener and the simulator are ``"module:attr"``
paths, imported only when used (``load``) by the factory and by the simulated rig, so
that the config imports no driver and the rig core no simulator.

Adding a gauge: a driver module with an opener ``open_x(cfg, ctx) -> gauge``, a
simulator module with ``simulate(world, clock, *, transport, rate_hz) -> ServedDevice``
(``rig/sim/served.py``), and one ``DeviceKind`` row in ``BUILT_IN`` below.
"""

from __future__ import annotations

import contextlib
import importlib
from dataclasses import dataclass
from typing import Any, Iterator

from common.errors import ConfigError

ROLES = ("axis", "gauge", "camera")
REQUIRED: Any = ...  # a key's default when the config must give it

# Bounds shared by the rows and the role keys in rig.config; each is far outside any sane
# setting but close enough that a typo cannot disarm a limit or overflow a native unit.
TRAVEL_LIMIT = 1e4  # mm or deg: 10 m of linear travel, or ~28 turns; no lab stage goes further
MAX_TIMEOUT_S = 60.0  # a device that needs longer than a minute to answer is not answering
MAX_BAUDRATE = 12_000_000  # the fastest USB-serial bridges (FTDI FT232H) top out at 12 Mbaud
MAX_PULSES_PER_REV = 0xFFFF  # the drive holds pulses/rev in one 16-bit register (rig/drivers/pr_registers.py)


@dataclass(frozen=True)
class Key:
    """One config key: its TOML type, default (``REQUIRED``: must be given) and allowed values.

    ``min_abs``: the smallest magnitude allowed (a scale or gear ratio must not be ~0).
    """

    name: str
    kind: type
    default: Any = REQUIRED
    low: float | None = None
    high: float | None = None
    positive: bool = False
    choices: tuple | None = None
    min_abs: float | None = None
    doc: str = ""


@dataclass(frozen=True)
class Wire:
    """Default wire settings. ``baudrate=None``: not a serial device, the key is refused."""

    baudrate: int | None = None
    timeout_s: float = 0.5  # per exchange
    retries: int = 2  # idempotent exchanges repeated on a timeout or a garbled reply


@dataclass(frozen=True)
class DeviceKind:
    """A row of the registry.

    opener: ``"module:function"``, called as ``function(cfg, ctx: OpenContext)``; returns
      the axis, the gauge (not yet streaming) or the camera's capture source.
    simulator: ``"module:function"``, called as ``function(world, clock, *, transport,
      rate_hz)`` by the simulated rig; returns a ``rig.sim.served.ServedDevice``. None: the
      simulated rig cannot stand this kind in (the axes: its layout is fixed).
    """

    role: str
    name: str
    title: str  # what `rig status` prints beside the device
    opener: str
    keys: tuple[Key, ...] = ()
    wire: Wire = Wire()
    simulator: str | None = None


@dataclass
class OpenContext:
    """What an opener may use besides its config section."""

    clock: Any  # rig.clock.Clock: stamps samples and frames
    ports: Any  # rig.factory.PortPool: ``ports.shared(url, open)``, one transport per port
    sim: Any = None  # the in-process simulated rig (``--sim``), else None


BUILT_IN = (
    DeviceKind(
        "axis",
        "zaber",
        "Zaber stage (ASCII)",
        "rig.openers:open_zaber",
        wire=Wire(baudrate=115200),
        keys=(
            # unit per microstep: 1e-9 mm is far below any microstep (positions become int
            # microsteps, so a tinier scale overflows them); more than 1000 per step is no stage
            Key(
                "scale", float, low=-1e3, high=1e3, min_abs=1e-9, doc="unit per microstep; negative flips the direction"
            ),
            Key("axis_number", int, 1, low=1, high=9, doc="axis of a multi-axis controller"),
        ),
    ),
    DeviceKind(
        "axis",
        "pr_drive",
        "PR-mode drive (Modbus RTU)",
        "rig.openers:open_pr_drive",
        wire=Wire(baudrate=38400),
        keys=(
            Key("pulses_per_rev", int, positive=True, high=MAX_PULSES_PER_REV, doc="must match the drive"),
            # below 1 nm (or µdeg) per motor turn no gearbox exists
            Key(
                "travel_per_rev",
                float,
                low=-TRAVEL_LIMIT,
                high=TRAVEL_LIMIT,
                min_abs=1e-6,
                doc="unit per motor revolution",
            ),
        ),
    ),
    DeviceKind(
        "gauge",
        "ft300",
        "Robotiq FT300 (Modbus RTU)",
        "rig.openers:open_ft300",
        wire=Wire(baudrate=19200),
        keys=(Key("device_id", int, 9, low=1, high=247, doc="Modbus id"),),
        simulator="rig.sim.served:simulate_ft300",
    ),
    DeviceKind(
        "gauge",
        "m8128",
        "SRI M8128 (serial or TCP)",
        "rig.openers:open_m8128",
        wire=Wire(baudrate=115200),
        keys=(Key("rate_hz", int, 100, low=1, high=2000, doc="sampling rate set with AT+SMPF"),),
        simulator="rig.sim.served:simulate_m8128",
    ),
    DeviceKind(
        "gauge",
        "ati_netft",
        "ATI Net F/T (UDP RDT)",
        "rig.openers:open_ati_netft",
        wire=Wire(),
        keys=(
            Key("rdt_port", int, 49152, low=1, high=65535, doc="UDP port of RDT (port is the box's host address)"),
            Key("http_port", int, 80, low=1, high=65535, doc="where netftapi2.xml (counts per unit) is served"),
            Key("rdt_mode", str, "realtime", choices=("realtime", "buffered")),
        ),
        simulator="rig.sim.served:simulate_ati_netft",
    ),
    DeviceKind(
        "camera",
        "v4l2",
        "UVC camera (V4L2)",
        "rig.openers:open_v4l2_camera",
        keys=(Key("device", str, doc="/dev/video0"),),
    ),
    DeviceKind(
        "camera",
        "folder",
        "recorded frames (folder of images)",
        "rig.openers:open_folder_camera",
        keys=(Key("device", str, doc="the folder"),),
    ),
    DeviceKind(
        "camera",
        "video",
        "recorded frames (video file)",
        "rig.openers:open_video_camera",
        keys=(Key("device", str, doc="the video file"),),
    ),
    DeviceKind(
        "camera",
        "sim",
        "simulated tactile camera (in-process, --sim)",
        "rig.openers:open_sim_camera",
        keys=(Key("device", str, ""),),
    ),
    DeviceKind(
        "camera",
        "stream",
        "camera stream over TCP (`rig sim serve`)",
        "rig.openers:open_stream_camera",
        keys=(
            Key("device", str, doc="tcp://HOST:PORT"),
            Key("timeout_s", float, 2.0, positive=True, high=MAX_TIMEOUT_S, doc="for one frame"),
        ),
    ),
)

_rows: dict[tuple[str, str], DeviceKind] = {}


def register(row: DeviceKind) -> DeviceKind:
    """Add a kind; a second row for the same role and name is a mistake, not an override."""
    if row.role not in ROLES:
        raise ValueError(f"device kind {row.name!r}: role must be one of {', '.join(ROLES)}, got {row.role!r}")
    if (row.role, row.name) in _rows:
        raise ValueError(f"{row.role} kind {row.name!r} is already registered")
    _rows[(row.role, row.name)] = row
    return row


def unregister(role: str, name: str) -> None:
    _rows.pop((role, name), None)


@contextlib.contextmanager
def registered(row: DeviceKind) -> Iterator[DeviceKind]:
    """A kind registered for the length of a ``with`` block (tests, plug-ins)."""
    register(row)
    try:
        yield row
    finally:
        unregister(row.role, row.name)


def kinds(role: str, *, simulated: bool = False) -> tuple[str, ...]:
    """The registered kind names of a role, in registration order (``simulated``: those
    the simulated rig can stand in)."""
    return tuple(r.name for r in _rows.values() if r.role == role and (r.simulator or not simulated))


def kind(role: str, name: str, *, path: str = "<config>", key: str | None = None) -> DeviceKind:
    """The row for ``name``; else a ConfigError naming the file, the key and the kinds known."""
    row = _rows.get((role, name))
    if row is None:
        known = ", ".join(map(repr, kinds(role)))
        raise ConfigError(path, key or f"{role}.driver", f"must be one of {known}, got {name!r}")
    return row


def load(ref: str) -> Any:
    """The object a ``"module:attr"`` path names, imported now (openers, simulators)."""
    module, _, attr = ref.partition(":")
    try:
        return getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as exc:
        raise ConfigError("<device registry>", ref, f"cannot load: {exc}") from exc


for _row in BUILT_IN:
    register(_row)
