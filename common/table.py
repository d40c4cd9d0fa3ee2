"""Reading TOML files and numbers that enter the project, with errors naming file and key.

Used by the rig config, protocol files, model files, import metadata, split ratios and
numeric command-line options alike: one checker, one wording. Imports nothing of the
project but its errors.
"""

from __future__ import annotations

import math
import tomllib
from typing import Any

from common.errors import ConfigError


def _bounds_text(low, high, positive: bool) -> str:
    """'> 0', '> 0 and <= 300.0', 'in [0.001, 1.0]', '>= 0', '<= 10'."""
    if positive and (low is None or low <= 0):
        return "> 0" + (f" and <= {high!r}" if high is not None else "")
    if low is not None and high is not None:
        return f"in [{low!r}, {high!r}]"
    return f">= {low!r}" if low is not None else f"<= {high!r}"


def number_problem(
    value: Any, *, low: float | None = None, high: float | None = None, positive: bool = False, integer: bool = False
) -> str | None:
    """What is wrong with ``value`` as a finite number within the bounds ("must be > 0, got
    -1.0"), or None when nothing is. NaN compares false with every bound, so a plain
    ``low <= value <= high`` would let it through; inf and huge ints overflow later arithmetic."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (integer and not isinstance(value, int)):
        return f"must be {'an integer' if integer else 'a number'}, got {value!r}"
    if not integer:
        try:
            value = float(value)
        except OverflowError:  # an int too large for a float: not a physical quantity
            return f"must be a finite number, got {value!r}"
        if not math.isfinite(value):
            return f"must be a finite number, got {value!r}"
    if (positive and value <= 0) or (low is not None and value < low) or (high is not None and value > high):
        return f"must be {_bounds_text(low, high, positive)}, got {value!r}"
    return None


def finite_number(
    path: str,
    key: str,
    value: Any,
    *,
    low: float | None = None,
    high: float | None = None,
    positive: bool = False,
    integer: bool = False,
) -> float | int:
    """``value`` as a float (an int when ``integer``) if it is a finite number within the
    bounds; else a one-line ConfigError naming ``path``, ``key`` and the value.

    The one checker for numbers entering the project: rig config, protocols and ``--set``,
    import metadata, split ratios, numeric command-line options (the command-line layer's ``number`` callback).
    """
    problem = number_problem(value, low=low, high=high, positive=positive, integer=integer)
    if problem:
        raise ConfigError(path, key, problem)
    return value if integer else float(value)


class Table:
    """Typed access to one TOML table, with errors naming file and key."""

    def __init__(self, path: str, prefix: str, data: Any):
        if not isinstance(data, dict):
            raise ConfigError(path, prefix, f"must be a table, got {type(data).__name__}")
        self.path, self.prefix, self.data = path, prefix, data
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.prefix}.{name}" if self.prefix else name

    def error(self, name: str, message: str) -> ConfigError:
        return ConfigError(self.path, self.key(name), message)

    def get(
        self, name: str, kind: type, default: Any = ..., *, choices=None, low=None, high=None, positive: bool = False
    ):
        """The value of ``name``; numbers (int, float) go through :func:`finite_number`."""
        self.used.add(name)
        if name not in self.data:
            if default is ...:
                one_of = f" (one of {', '.join(map(repr, choices))})" if choices else ""
                raise self.error(name, "is required" + one_of)
            return default
        value = self.data[name]
        if kind in (int, float):
            is_number = isinstance(value, (int, float)) and not isinstance(value, bool)
            if not is_number or (kind is int and not isinstance(value, int)):
                raise self.error(name, f"must be {kind.__name__}, got {value!r}")
            return finite_number(
                self.path, self.key(name), value, low=low, high=high, positive=positive, integer=kind is int
            )
        if not isinstance(value, kind):
            raise self.error(name, f"must be {kind.__name__}, got {value!r}")
        if choices is not None and value not in choices:
            raise self.error(name, f"must be one of {', '.join(map(repr, choices))}, got {value!r}")
        return value

    def vector(
        self, name: str, n: int, default: Any = ..., *, low=None, high=None, positive: bool = False
    ) -> tuple[float, ...]:
        """A list of ``n`` numbers, each checked like :meth:`get` (key ``name[i]``)."""
        self.used.add(name)
        if name not in self.data:
            if default is ...:
                raise self.error(name, f"is required (a list of {n} numbers)")
            return default
        value = self.data[name]
        if (
            not isinstance(value, list)
            or len(value) != n
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        ):
            raise self.error(name, f"must be a list of {n} numbers, got {value!r}")
        return tuple(
            finite_number(self.path, f"{self.key(name)}[{i}]", v, low=low, high=high, positive=positive)
            for i, v in enumerate(value)
        )

    def done(self) -> None:
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            raise self.error(unknown[0], f"unknown key; expected one of {', '.join(sorted(self.used))}")


def toml_table(text: str, path: str) -> tuple[Table, dict]:
    """The top-level table of a TOML text; a syntax error names the file."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(path, "-", f"not valid TOML: {exc}") from exc
    return Table(path, "", data), data
