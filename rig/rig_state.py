"""What a rig remembers between commands: the gauge's unloaded reading and the gel surface.

A motion session that is interrupted while pressed has to know whether it is pressed and
where the load began, whatever process it runs in. Two facts outlive a command:

- the **tare**: the raw (untared) wrench with nothing touching, and when it was taken
  (`rig zero`, the tare before a protocol run, find-contact's tare);
- the **gel surface**: the z (axis mm) where a load began, from `rig find-contact` or the
  first contact a motion session saw, and how it was found;
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

STATE_VERSION = 1


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
    """The remembered tare and gel surface of one rig; ``path`` None keeps them in memory."""

    def __init__(self, path: Path | None):
        self.path = path
        self.tare: Tare | None = None
        self.surface: Surface | None = None
        self.origin: Origin | None = None
        if path is not None and path.exists():
            self._load(path)

    @classmethod
    def for_config(cls, config) -> "RigState":
        return cls(state_path(config.path, config.name))

    # -- reading back, every value checked ---------------------------------------------
    def _load(self, path: Path) -> None:
        try:
            data = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ConfigError(str(path), "-", f"rig state is unreadable ({exc}); delete it to start afresh") from None
        if not isinstance(data, dict) or data.get("version") != STATE_VERSION:
            raise ConfigError(str(path), "version", f"expected rig state version {STATE_VERSION}; delete the file")
        tare = data.get("tare")
        if tare is not None:
            raw = _numbers(path, "tare.raw", _field(path, tare, "tare", "raw"), 6)
            self.tare = Tare(raw, _numbers(path, "tare.t_unix", [_field(path, tare, "tare", "t_unix")], 1)[0])
        surface = data.get("surface")
        if surface is not None:
            z = _numbers(path, "surface.z_mm", [_field(path, surface, "surface", "z_mm")], 1)[0]
            t = _numbers(path, "surface.t_unix", [_field(path, surface, "surface", "t_unix")], 1)[0]
            how = _field(path, surface, "surface", "how")
            if not isinstance(how, str):
                raise ConfigError(str(path), "surface.how", f"must be text, got {how!r}")
            self.surface = Surface(z, how, t)
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
        if not math.isfinite(z_mm):
            raise ValueError(f"a gel surface needs a finite z, got {z_mm!r}")
        self.surface = Surface(float(z_mm), how, time.time() if t_unix is None else t_unix)
        self.save()
        return self.surface

    def forget_surface(self) -> None:
        """Forget the gel surface (find-contact measures it anew: a new indenter may touch lower)."""
        self.surface = None
        self.save()

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
        data: dict[str, Any] = {"version": STATE_VERSION}
        if self.tare is not None:
            data["tare"] = {"raw": list(self.tare.raw_N), "t_unix": self.tare.t_unix}
        if self.surface is not None:
            data["surface"] = {"z_mm": self.surface.z_mm, "how": self.surface.how, "t_unix": self.surface.t_unix}
        if self.origin is not None:
            data["origin"] = {"xyzt": list(self.origin.values), "t_unix": self.origin.t_unix}
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


def _numbers(path: Path, key: str, values: Any, n: int) -> tuple[float, ...]:
    if (
        not isinstance(values, list)
        or len(values) != n
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values)
    ):
        raise ConfigError(str(path), key, f"must be {n} finite number(s), got {values!r}; delete the file")
    return tuple(float(v) for v in values)
