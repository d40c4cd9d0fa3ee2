"""What a rig remembers between commands: the gauge's unloaded reading and the gel surface.

A motion session that is interrupted while pressed has to know whether it is pressed and
where the load began, whatever process it runs in. Two facts outlive a command:

- the **tare**: the raw (untared) wrench with nothing touching, and when it was taken
  (`rig zero`, the tare before a protocol run, find-contact's tare);
- the **gel surface** of each indenter: the z (axis mm) where a load began, from `rig
  find-contact` or the first contact a motion session saw, how it was found, and what it belongs
  to: the indenter mounted (``--object``, a protocol's object), the z homing and the z
  controller's power-up it was measured under. A different indenter, a re-home, a power cycle
  (the token in the controller's volatile memory is gone: rig/surface_identity.py) or an age
  past [safety] surface_max_age_h makes it unknown;
- the z controller's own **travel limits** while a session has narrowed them to the depth floor
  (rig/device_floor.py), so that a later command restores those a killed process left;
- the **origin** (optional): the contact point x, y, z (mm), θ (deg) that `rig find-contact
  --set-origin` stored for `rig run-protocol`, and when.

They live in one small JSON file per rig config in a state folder
(``$TACTILE_STATE_DIR``, else ``$XDG_STATE_HOME/tactile-rig``, else
``~/.local/state/tactile-rig``), named after the rig and its config's absolute path, and are
written atomically (a temporary file, fsync, rename). Every number read back is checked;
a damaged file is one line naming it and the key. The built-in simulated rig of an
in-process ``--sim`` command is a new world each time: its state lives in memory only.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from common.errors import ConfigError

STATE_VERSION = 2
READABLE_VERSIONS = (1, 2)  # version 1: one surface without what it belongs to (read as unknown)


def state_dir() -> Path:
    env = os.environ.get("TACTILE_STATE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_STATE_HOME")
    return (Path(xdg) if xdg else Path(os.path.expanduser("~")) / ".local" / "state") / "tactile-rig"


def state_path(config_path: str, rig_name: str) -> Path | None:
    """The state file of the rig configured at ``config_path``; None for a config that is not
    a file (the in-process simulated rig's ``<built-in simulated rig>``)."""
    p = Path(config_path)
    if config_path.startswith("<") or not p.is_file():
        return None
    key = hashlib.sha1(str(p.resolve()).encode()).hexdigest()[:12]
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "-", rig_name).strip("-")[:40] or "rig"
    return state_dir() / f"{slug}-{key}.json"


@dataclass(frozen=True)
class Tare:
    raw_N: tuple[float, ...]  # the unloaded raw wrench: Fx, Fy, Fz (N), Mx, My, Mz (N·mm)
    t_unix: float  # when it was taken (wall clock, for its age)

    @property
    def fz_N(self) -> float:
        return self.raw_N[2]


@dataclass(frozen=True)
class Surface:
    z_mm: float  # axis z where a load began
    how: str  # "find-contact", "first contact (jog)", ...
    t_unix: float
    indenter: str = ""  # the object mounted when it was measured ("": none named)
    power_token: int | None = None  # the z controller's power-up token then (None: not known)
    z_homed_unix: float | None = None  # when z had last been homed then (None: not by this tool)


@dataclass(frozen=True)
class DeviceLimits:
    """A controller's travel limits as a session found them (``saved``, native units) and as it
    narrowed them (``narrowed``), by ``pid`` at ``t_unix``: written before the narrowing."""

    saved: tuple[int, int]
    narrowed: tuple[int, int]
    pid: int
    t_unix: float


@dataclass(frozen=True)
class Origin:
    """The contact point a protocol starts from, in axis coordinates (``rig find-contact --set-origin``)."""

    x_mm: float
    y_mm: float
    z_mm: float
    theta_deg: float
    t_unix: float

    @property
    def values(self) -> tuple[float, float, float, float]:
        return (self.x_mm, self.y_mm, self.z_mm, self.theta_deg)

    def text(self) -> str:
        """'X,Y,Z,THETA' as ``--origin`` takes it."""
        return ",".join(f"{round(v, 4) + 0.0:.4f}" for v in self.values)  # + 0.0: never "-0.0000"


class RigState:
    """The remembered tare, gel surfaces, origin and controller limits of one rig; ``path`` None
    keeps them in memory. ``surface`` is the one that belongs to what the rig is now: the mounted
    indenter's, measured under this power-up of the z controller and this homing, and not older
    than ``max_age_s`` (``why_unknown`` says which of these failed)."""

    def __init__(self, path: Path | None):
        self.path = path
        self.tare: Tare | None = None
        self.surfaces: dict[str, Surface] = {}
        self.mounted = ""  # the indenter named last (``--object``, a protocol's object); "": none
        self.power_token: int | None = None  # the token in the z controller now (None: it holds none)
        self.z_homed_unix: float | None = None  # when this tool last homed z
        self.device_limits: dict[str, DeviceLimits] = {}
        self.origin: Origin | None = None
        self.envelope: dict[str, float] = {}  # the last speed envelope measured: its inputs and z's cap in contact
        self.max_age_s = math.inf
        if path is not None and path.exists():
            self._load(path)

    @classmethod
    def for_config(cls, config) -> "RigState":
        state = cls(state_path(config.path, config.name))
        if config.safety is not None:
            state.max_age_s = config.safety.surface_max_age_h * 3600.0
        return state

    # -- the surface that belongs to the rig as it is ---------------------------------------
    def why_unknown(self, surface: Surface | None, now_unix: float | None = None) -> str | None:
        """Why ``surface`` does not belong to the rig as it is now; None when it does."""
        if surface is None:
            return f"none measured with {self.mounted or 'the indenter'}"
        if self.power_token is not None and surface.power_token != self.power_token:
            return "the z controller was powered off and on since it was measured"
        if surface.z_homed_unix != self.z_homed_unix:
            return "z was homed since it was measured"
        age = (time.time() if now_unix is None else now_unix) - surface.t_unix
        if age > self.max_age_s:
            return f"measured {age_text(surface.t_unix)}, more than {self.max_age_s / 3600:g} h ago"
        return None

    @property
    def surface(self) -> Surface | None:
        found = self.surfaces.get(self.mounted)
        return found if self.why_unknown(found) is None else None

    @surface.setter
    def surface(self, value: Surface | None) -> None:  # in memory only (tests stand in a rig's past)
        if value is None:
            self.surfaces.pop(self.mounted, None)
        else:
            self.surfaces[self.mounted] = value

    def mount(self, indenter: str | None) -> str | None:
        """The indenter now on the rig (None: unchanged). Returns a note when it changed."""
        if indenter is None or indenter == self.mounted:
            return None
        before, self.mounted = self.mounted, indenter
        self.save()
        known = self.surfaces.get(indenter)
        has = "" if known is None else f"; its surface, measured {age_text(known.t_unix)}, is remembered"
        return f"indenter {indenter} mounted (was {before or 'unnamed'}){has}"

    # -- reading back, every value checked ---------------------------------------------
    def _load(self, path: Path) -> None:
        try:
            data = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ConfigError(str(path), "-", f"rig state is unreadable ({exc}); delete it to start afresh") from None
        if not isinstance(data, dict) or data.get("version") not in READABLE_VERSIONS:
            raise ConfigError(str(path), "version", f"expected rig state version {STATE_VERSION}; delete the file")
        tare = data.get("tare")
        if tare is not None:
            raw = _numbers(path, "tare.raw", _field(path, tare, "tare", "raw"), 6)
            self.tare = Tare(raw, _numbers(path, "tare.t_unix", [_field(path, tare, "tare", "t_unix")], 1)[0])
        if data.get("version") == 1 and data.get("surface") is not None:
            self.surfaces[""] = _surface(path, "surface", data["surface"])
        for name, surface in _table(path, "surfaces", data.get("surfaces", {})).items():
            self.surfaces[name] = _surface(path, f"surfaces.{name}", surface)
        self.mounted = _text(path, "mounted", data.get("mounted", ""))
        self.power_token = _optional_int(path, "power_token", data.get("power_token"))
        homed = data.get("z_homed_unix")
        self.z_homed_unix = None if homed is None else _numbers(path, "z_homed_unix", [homed], 1)[0]
        for axis, limits in _table(path, "device_limits", data.get("device_limits", {})).items():
            key = f"device_limits.{axis}"
            saved = _ints(path, f"{key}.saved", _field(path, limits, key, "saved"), 2)
            narrowed = _ints(path, f"{key}.narrowed", _field(path, limits, key, "narrowed"), 2)
            pid = _ints(path, f"{key}.pid", [_field(path, limits, key, "pid")], 1)[0]
            t = _numbers(path, f"{key}.t_unix", [_field(path, limits, key, "t_unix")], 1)[0]
            self.device_limits[axis] = DeviceLimits((saved[0], saved[1]), (narrowed[0], narrowed[1]), pid, t)
        envelope = _table(path, "envelope", data.get("envelope", {}))
        self.envelope = {k: _numbers(path, f"envelope.{k}", [v], 1)[0] for k, v in envelope.items()}
        origin = data.get("origin")
        if origin is not None:
            x, y, z, theta = _numbers(path, "origin.xyzt", _field(path, origin, "origin", "xyzt"), 4)
            t = _numbers(path, "origin.t_unix", [_field(path, origin, "origin", "t_unix")], 1)[0]
            self.origin = Origin(x, y, z, theta, t_unix=t)

    # -- remembering ----------------------------------------------------------------------
    def remember_tare(self, raw, t_unix: float | None = None) -> Tare:
        values = tuple(float(v) for v in raw)
        if len(values) != 6 or not all(math.isfinite(v) for v in values):
            raise ValueError(f"a tare needs six finite numbers, got {list(raw)!r}")
        self.tare = Tare(values, time.time() if t_unix is None else t_unix)
        self.save()
        return self.tare

    def remember_surface(self, z_mm: float, how: str, t_unix: float | None = None) -> Surface:
        """The gel surface of the mounted indenter, under this power-up and homing of z."""
        if not math.isfinite(z_mm):
            raise ValueError(f"a gel surface needs a finite z, got {z_mm!r}")
        surface = Surface(
            float(z_mm),
            how,
            time.time() if t_unix is None else t_unix,
            self.mounted,
            self.power_token,
            self.z_homed_unix,
        )
        self.surfaces[self.mounted] = surface
        self.save()
        return surface

    def forget_surface(self) -> None:
        """Forget the mounted indenter's surface (find-contact measures it anew)."""
        self.surfaces.pop(self.mounted, None)
        self.save()

    def note_power_token(self, token: int | None) -> None:
        """The token now in the z controller (surfaces measured under another become unknown)."""
        if token != self.power_token:
            self.power_token = token
            self.save()

    def note_z_homed(self, t_unix: float | None = None) -> None:
        """z was homed: every remembered surface becomes unknown (docs/safety.md)."""
        self.z_homed_unix = time.time() if t_unix is None else t_unix
        self.save()

    def remember_device_limits(self, axis: str, limits: DeviceLimits | None) -> None:
        if limits is None:
            if self.device_limits.pop(axis, None) is not None:
                self.save()
            return
        self.device_limits[axis] = limits
        self.save()

    def remember_envelope(self, values: dict[str, float]) -> dict[str, float]:
        """The newly measured envelope's summary; returns the one remembered before it."""
        before, self.envelope = self.envelope, {k: float(v) for k, v in values.items() if math.isfinite(v)}
        if self.envelope != before:
            self.save()
        return before

    def remember_origin(self, values, t_unix: float | None = None) -> Origin:
        """Store the contact point x, y, z (mm), θ (deg) for ``rig run-protocol``."""
        numbers = tuple(float(v) for v in values)
        if len(numbers) != 4 or not all(math.isfinite(v) for v in numbers):
            raise ValueError(f"an origin needs four finite numbers x, y, z, theta, got {list(values)!r}")
        x, y, z, theta = numbers
        self.origin = Origin(x, y, z, theta, t_unix=time.time() if t_unix is None else t_unix)
        self.save()
        return self.origin

    def forget_origin(self) -> Origin | None:
        """Forget the stored origin (a new contact was measured, or the axes changed); returns it."""
        old, self.origin = self.origin, None
        if old is not None:
            self.save()
        return old

    def save(self) -> None:
        if self.path is None:
            return
        data: dict[str, Any] = {"version": STATE_VERSION, "mounted": self.mounted}
        if self.tare is not None:
            data["tare"] = {"raw": list(self.tare.raw_N), "t_unix": self.tare.t_unix}
        data["surfaces"] = {
            name: {
                "z_mm": s.z_mm,
                "how": s.how,
                "t_unix": s.t_unix,
                "indenter": s.indenter,
                "power_token": s.power_token,
                "z_homed_unix": s.z_homed_unix,
            }
            for name, s in self.surfaces.items()
        }
        data["power_token"] = self.power_token
        data["z_homed_unix"] = self.z_homed_unix
        data["device_limits"] = {
            axis: {"saved": list(d.saved), "narrowed": list(d.narrowed), "pid": d.pid, "t_unix": d.t_unix}
            for axis, d in self.device_limits.items()
        }
        if self.origin is not None:
            data["origin"] = {"xyzt": list(self.origin.values), "t_unix": self.origin.t_unix}
        data["envelope"] = dict(self.envelope)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f"{self.path.name}.{os.getpid()}.tmp")
        with open(tmp, "w") as f:
            json.dump(data, f, indent=1)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self.path)
        folder = os.open(self.path.parent, os.O_RDONLY)
        try:  # the rename itself survives a power cut
            os.fsync(folder)
        finally:
            os.close(folder)


def age_text(t_unix: float, now_unix: float | None = None) -> str:
    """'3 s', '12 min', '5 h', '2 d' ago."""
    age = max(0.0, (time.time() if now_unix is None else now_unix) - t_unix)
    for unit, size in (("d", 86400), ("h", 3600), ("min", 60)):
        if age >= size:
            return f"{age / size:.0f} {unit} ago"
    return f"{age:.0f} s ago"


def _field(path: Path, table: Any, name: str, key: str) -> Any:
    if not isinstance(table, dict) or key not in table:
        raise ConfigError(str(path), f"{name}.{key}", "is missing from the rig state; delete the file")
    return table[key]


def _table(path: Path, key: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
        raise ConfigError(str(path), key, f"must be a table, got {value!r}; delete the file")
    return value


def _text(path: Path, key: str, value: Any) -> str:
    if not isinstance(value, str):
        raise ConfigError(str(path), key, f"must be text, got {value!r}; delete the file")
    return value


def _optional_int(path: Path, key: str, value: Any) -> int | None:
    return None if value is None else _ints(path, key, [value], 1)[0]


def _ints(path: Path, key: str, values: Any, n: int) -> tuple[int, ...]:
    if (
        not isinstance(values, list)
        or len(values) != n
        or not all(isinstance(v, int) and not isinstance(v, bool) and abs(v) < 2**63 for v in values)
    ):
        raise ConfigError(str(path), key, f"must be {n} integer(s), got {values!r}; delete the file")
    return tuple(values)


def _surface(path: Path, key: str, table: Any) -> Surface:
    z = _numbers(path, f"{key}.z_mm", [_field(path, table, key, "z_mm")], 1)[0]
    t = _numbers(path, f"{key}.t_unix", [_field(path, table, key, "t_unix")], 1)[0]
    how = _text(path, f"{key}.how", _field(path, table, key, "how"))
    indenter = _text(path, f"{key}.indenter", table.get("indenter", ""))
    token = _optional_int(path, f"{key}.power_token", table.get("power_token"))
    homed = table.get("z_homed_unix")
    homed_at = None if homed is None else _numbers(path, f"{key}.z_homed_unix", [homed], 1)[0]
    return Surface(z, how, t, indenter, token, homed_at)


def _numbers(path: Path, key: str, values: Any, n: int) -> tuple[float, ...]:
    if (
        not isinstance(values, list)
        or len(values) != n
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values)
    ):
        raise ConfigError(str(path), key, f"must be {n} finite number(s), got {values!r}; delete the file")
    return tuple(float(v) for v in values)
