"""A protocol run's progress beside its run file, for the console to show while it runs.

``rig run-protocol`` writes ``RUN.h5.progress.json`` next to the run file (``ProgressWriter``):
the protocol, phase, level and its depth, frames done of planned, an ETA, at most twice a
second, each time whole (a temporary file, then ``os.replace``, so a reader never sees half
of one). It removes the file when the run ends; the run file's own status then says how it
ended. The console reads it with ``read_progress``, which checks every value, since the
file may be from another version, hand-edited or left by a writer that was killed.

Light on purpose (json, os, time): the command line imports it before a run starts.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from common.eta import time_left

SUFFIX = ".progress.json"
WRITE_EVERY_S = 0.5  # at most two writes a second: a few hundred bytes each
STALE_AFTER_S = 30.0  # no write for this long: the writer is gone (or hung)
VERSION = 1


def sidecar_path(run: Path) -> Path:
    """Where the progress of ``run`` is written: ``RUN.h5.progress.json`` beside it."""
    return run.with_name(run.name + SUFFIX)


class ProgressWriter:
    """Writes the sidecar from the executor's progress callback (``update``), throttled to
    ``every_s`` on the ``now`` clock; the first update, a change of phase or level and the last
    frame are always written. ``close`` removes it. Failures to write are counted, never raised:
    a full disk must not stop a run that is moving stages (the run file then fails loudly)."""

    def __init__(
        self,
        run: Path,
        *,
        protocol: str,
        frames: int,
        levels_mm: Sequence[float],
        now: Callable[[], float] = time.monotonic,
        wall: Callable[[], float] = time.time,
        every_s: float = WRITE_EVERY_S,
    ):
        self.path = sidecar_path(Path(run))
        self.run_name = Path(run).name
        self.protocol = protocol
        self.frames = frames
        self.levels_mm = list(levels_mm)
        self._now, self._wall, self._every_s = now, wall, every_s
        self._last_write = -math.inf
        self._last_key: tuple | None = None
        self._first: tuple[float, int] | None = None  # (now, frame) of the first update: the rate for the ETA
        self.started_at = wall()
        self.writes = 0
        self.failures = 0

    def update(self, p) -> None:
        """One ``acquisition.executor.Progress``: frame (done), frames, phase, level,
        t_protocol_s, duration_s, wrench. Never raises: the run matters more than its sidecar."""
        try:
            self._update(p)
        except (TypeError, ValueError, IndexError, OSError):
            self.failures += 1

    def _update(self, p) -> None:
        now = self._now()
        if self._first is None:
            self._first = (now, p.frame)
        key = (p.phase, p.level)
        due = now - self._last_write >= self._every_s or key != self._last_key or p.frame >= p.frames
        if not due:
            return
        self._last_key = key
        self._last_write = now
        t0, f0 = self._first
        done = p.frame - f0
        remaining = max(0, p.frames - p.frame)
        # wall seconds per frame so far (a simulated run is faster or slower than protocol time)
        left = time_left(done, done + remaining, now - t0) if now > t0 else None
        eta_s = left if left is not None else max(0.0, p.duration_s - p.t_protocol_s)
        level = int(p.level)
        depth = self.levels_mm[level - 1] if 1 <= level <= len(self.levels_mm) else None
        self._write(
            {
                "version": VERSION,
                "run": self.run_name,
                "protocol": self.protocol,
                "pid": os.getpid(),
                "status": "running",
                "phase": str(p.phase),
                "level": level,
                "depth_mm": depth,
                "frame": int(p.frame),
                "frames": int(p.frames),
                "t_protocol_s": float(p.t_protocol_s),
                "duration_s": float(p.duration_s),
                "eta_s": float(eta_s),
                "wrench": [float(v) for v in p.wrench],
                "started_at": self.started_at,
                "updated_at": self._wall(),
            }
        )

    def _write(self, record: dict) -> None:
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        try:
            tmp.write_text(json.dumps(record))
            os.replace(tmp, self.path)
            self.writes += 1
        except OSError:
            self.failures += 1
            tmp.unlink(missing_ok=True)

    def close(self) -> None:
        """The run has ended (its file says how): remove the sidecar."""
        try:
            self.path.unlink(missing_ok=True)
        except OSError:
            self.failures += 1

    def __enter__(self) -> ProgressWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class BadProgress(ValueError):
    """A sidecar that is not one this version writes; the message names file, key and value."""


def _check_number(path: Path, record: dict, key: str, *, low: float = 0.0, high: float = math.inf, whole=False):
    value = record.get(key)
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        number = float(value)
        if math.isfinite(number) and low <= number <= high and (not whole or number.is_integer()):
            return int(number) if whole else number
    kind = "a whole number" if whole else "a number"
    raise BadProgress(f"{path.name}: {key} = {value!r}, expected {kind} in {low:g}..{high:g}")


def read_progress(path: Path, wall: Callable[[], float] = time.time) -> dict:
    """The sidecar at ``path``, every value checked; BadProgress (one line) otherwise. Adds
    ``age_s`` (since its last write, on the ``wall`` clock) and ``stale`` (no write for
    STALE_AFTER_S)."""
    try:
        record = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BadProgress(f"{path.name}: not readable as JSON ({exc})") from None
    if not isinstance(record, dict) or record.get("version") != VERSION:
        got = record.get("version") if isinstance(record, dict) else type(record).__name__
        raise BadProgress(f"{path.name}: version {got!r}, expected {VERSION}")
    out: dict = {}
    for key in ("run", "protocol", "phase", "status"):
        if not isinstance(record.get(key), str) or len(record[key]) > 200:
            raise BadProgress(f"{path.name}: {key} = {record.get(key)!r}, expected a short text")
        out[key] = record[key]
    frames = _check_number(path, record, "frames", low=1, high=10**9, whole=True)
    out["frames"] = frames
    out["frame"] = _check_number(path, record, "frame", high=frames, whole=True)
    out["level"] = _check_number(path, record, "level", high=10**6, whole=True)
    out["pid"] = _check_number(path, record, "pid", high=2**31, whole=True)
    for key in ("t_protocol_s", "duration_s", "eta_s", "started_at", "updated_at"):
        out[key] = _check_number(path, record, key)
    depth = record.get("depth_mm")
    out["depth_mm"] = None if depth is None else _check_number(path, record, "depth_mm", high=1000.0)
    wrench = record.get("wrench")
    if not (isinstance(wrench, list) and len(wrench) == 6):
        raise BadProgress(f"{path.name}: wrench = {wrench!r}, expected 6 numbers (N, N·mm)")
    out["wrench"] = [_check_number(path, {"wrench": v}, "wrench", low=-math.inf) for v in wrench]  # finite, any sign
    out["age_s"] = max(0.0, wall() - out["updated_at"])
    out["stale"] = out["age_s"] > STALE_AFTER_S
    return out
