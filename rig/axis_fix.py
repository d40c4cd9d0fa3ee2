"""Write the fix ``rig check-axes --fix`` found into the rig config (rig/axis_verdict.py's ``AxisFix``).

Two kinds of change, both made in the config's own text so that its comments and layout stay:

- **swap**: the ``[axes.x]`` and ``[axes.y]`` tables change names (a stage's port, device,
  scale, offset and travel go with it: they describe that stage);
- **reverse**: an axis's direction key (a Zaber stage's ``scale``, a PR drive's
  ``travel_per_rev``), its ``offset`` and its ``travel`` are negated, so that every position
  keeps its magnitude and only its sign changes (the contact point stays at the same number).

The new text is parsed by the config's own validator and compared key by key with what the
fix means; anything else (axes written as inline tables, a driver without a direction key) is
refused in one line saying what to change by hand. The file is replaced atomically (a
temporary file, fsync, rename) after a copy of the old one is kept beside it.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import time
import tomllib
from pathlib import Path

from common.errors import ConfigError
from rig.axis_verdict import AxisFix
from rig.config import AxisConfig, RigConfig, parse_config

DIRECTION_KEYS = {"zaber": "scale", "pr_drive": "travel_per_rev"}  # the key whose sign is the direction
HEADER = re.compile(r"^(\s*)\[\s*([A-Za-z0-9_.-]+)\s*\](.*)$")
KEY_LINE = re.compile(r"^(\s*)([A-Za-z0-9_]+)(\s*=\s*)([^#\r\n]*?)(\s*(?:#[^\r\n]*)?)(\r?\n?)$")


def fixed_config_text(text: str, path: str, fix: AxisFix) -> str:
    """The config ``text`` with ``fix`` applied; ConfigError (one line) when it cannot be done safely."""
    old = parse_config(text, path)
    renames = {old_name: new for new, (old_name, _) in zip(("x", "y"), fix.xy) if old_name != new}
    reversed_ = {new for new, (_, sign) in zip(("x", "y"), fix.xy) if sign < 0}
    if fix.theta_sign < 0:
        reversed_.add("theta")
    source = {new: old_name for new, (old_name, _) in zip(("x", "y"), fix.xy)}
    source["theta"] = "theta"
    keys = {}
    for new in reversed_:
        cfg = old.axes.get(source[new])
        if cfg is None:
            raise ConfigError(path, f"axes.{source[new]}", "is not configured; nothing to reverse")
        if cfg.driver not in DIRECTION_KEYS:
            raise ConfigError(
                path, f"axes.{source[new]}", f"driver {cfg.driver!r}: reverse its direction by hand ({_by_hand(new)})"
            )
        keys[new] = DIRECTION_KEYS[cfg.driver]
    out, table = [], None
    for line in text.splitlines(keepends=True):
        body = line.rstrip("\r\n")
        header = HEADER.match(body)
        if header and not body.lstrip().startswith("[["):
            parts = header.group(2).split(".")
            if len(parts) >= 2 and parts[0] == "axes" and parts[1] in renames:
                parts[1] = renames[parts[1]]
                line = f"{header.group(1)}[{'.'.join(parts)}]{header.group(3)}{line[len(body) :]}"
            table = ".".join(parts)
        elif table is not None and table.startswith("axes.") and table.count(".") == 1:
            axis = table.split(".")[1]
            if axis in reversed_:
                line = _negated(line, keys[axis], path, axis)
        out.append(line)
    new_text = "".join(out)
    _verify(old, new_text, path, source, reversed_, keys)
    return new_text


def _negated(line: str, direction_key: str, path: str, axis: str) -> str:
    m = KEY_LINE.match(line)
    if not m or m.group(2) not in (direction_key, "offset", "travel"):
        return line
    try:
        value = tomllib.loads(f"v = {m.group(4)}")["v"]
    except tomllib.TOMLDecodeError:
        raise ConfigError(path, f"axes.{axis}.{m.group(2)}", f"cannot be rewritten ({_by_hand(axis)})") from None
    if m.group(2) == "travel":
        new = f"[{_number(-value[1])}, {_number(-value[0])}]"
    else:
        new = _number(-value)
    return f"{m.group(1)}{m.group(2)}{m.group(3)}{new}{m.group(5)}{m.group(6)}"


def _number(v) -> str:
    return repr(float(v)) if isinstance(v, float) else str(v)


def _by_hand(axis: str) -> str:
    key = "scale (zaber) or travel_per_rev (pr_drive)"
    return f"negate {key}, offset and both ends of travel in [axes.{axis}], swapping travel's ends"


def _expected(cfg: AxisConfig, new: str, reverse: bool, key: str | None) -> AxisConfig:
    if not reverse or key is None:
        return dataclasses.replace(cfg, name=new)
    options = dict(cfg.options)
    options[key] = -options[key]
    return dataclasses.replace(
        cfg, name=new, offset=-cfg.offset, travel=(-cfg.travel[1], -cfg.travel[0]), options=options
    )


def _verify(old: RigConfig, new_text: str, path: str, source: dict, reversed_: set, keys: dict) -> None:
    new = parse_config(new_text, path)
    problems = [
        name for name in ("gauge", "camera", "safety", "pendant", "name") if getattr(new, name) != getattr(old, name)
    ]
    if set(new.axes) != set(old.axes):
        problems.append("axes")
    for name in new.axes:
        origin = source.get(name, name)
        want = _expected(old.axes[origin], name, name in reversed_, keys.get(name))
        if new.axes[name] != want:
            problems.append(f"axes.{name}")
    if problems:
        raise ConfigError(
            path,
            problems[0],
            "could not be rewritten automatically (axes must be [axes.NAME] tables with one key per line): "
            "make the change check-axes printed by hand",
        )


def write_config(path: Path, text: str, *, now: float | None = None) -> Path:
    """Replace the config at ``path`` (a link: its target) with ``text`` atomically, after copying
    the old file to ``NAME.bak-YYYYmmdd-HHMMSS`` beside it; returns the backup's path."""
    target = path.resolve()
    stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(time.time() if now is None else now))
    backup = target.with_name(f"{target.name}.bak-{stamp}")
    n = 1
    while backup.exists():
        backup = target.with_name(f"{target.name}.bak-{stamp}-{n}")
        n += 1
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    try:
        shutil.copy2(target, backup)
        with open(tmp, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        shutil.copymode(target, tmp)
        os.replace(tmp, target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise ConfigError(str(path), "-", f"cannot write the fixed config: {exc.strerror or exc}") from None
    folder = os.open(target.parent, os.O_RDONLY)
    try:  # the rename itself survives a power cut
        os.fsync(folder)
    finally:
        os.close(folder)
    return backup
