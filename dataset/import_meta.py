"""An import folder's run.json: its keys checked one by one, and what they give the imported run.

``read_meta`` checks run.json key by key (each error names the file, the key and the value);
``sensor_kind``, ``imported_status``, ``planned_frames`` and ``imported_profile`` settle the run
file's sensor kind, status and reason, planned frames and sensor profile from it and the import's
options: an exported run's status (an aborted or interrupted run stays incomplete), its planned
frames and its sensor profile come back with it. frames.csv's checks: dataset/import_checks.py.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

from acquisition import schema as S
from acquisition.writer_lock import RunFileError
from common.errors import ConfigError
from common.sensors import SENSOR_KINDS
from common.table import finite_number

META_KEYS = (
    "mm_per_px",
    "object",
    "object_geometry",
    "sensor",
    "protocol",
    "capture_hz",
    "status",
    "reason",
    "frames_planned",
    "sensor_profile",
    "phases",
    "pose_convention",
)
FRAMES_PLANNED = 10**9  # a whole number of frames up to this: a billion frames is years of capture
MM_PER_PX = (1e-4, 10.0)  # a GelSight Mini is 0.0634 mm/px at 320x240; beyond these no camera sees a gel
CAPTURE_HZ = (0.01, 1000.0)  # one frame a 100 s up to a fast camera's frame rate


def read_meta(folder: Path) -> dict:
    """run.json checked key by key; ConfigError names the file, the key and the value."""
    path = folder / "run.json"
    if not path.exists():
        return {}
    regular_file(path)
    try:
        meta = json.loads(path.read_text(encoding="utf-8-sig"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise ConfigError(str(path), "-", f"not valid JSON: {exc}") from None
    if not isinstance(meta, dict):
        raise ConfigError(str(path), "-", f"must be a JSON object of {', '.join(META_KEYS)}, got {type(meta).__name__}")
    for key, value in meta.items():
        if key not in META_KEYS:
            raise ConfigError(str(path), key, f"unknown key; expected one of {', '.join(META_KEYS)}")
        if key == "mm_per_px" and value is not None:
            finite_number(str(path), key, value, low=MM_PER_PX[0], high=MM_PER_PX[1])
        elif key == "capture_hz":
            finite_number(str(path), key, value, low=CAPTURE_HZ[0], high=CAPTURE_HZ[1])
        elif key == "status" and value not in S.STATUSES:
            raise ConfigError(str(path), key, f"must be one of {', '.join(S.STATUSES)}, got {value!r}")
        elif key == "frames_planned" and not (
            isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= FRAMES_PLANNED
        ):
            raise ConfigError(
                str(path), key, f"must be a whole number of frames from 1 to {FRAMES_PLANNED}, got {value!r}"
            )
        elif key == "sensor_profile":
            _profile_record(path, value)
        elif key == "phases":
            if (
                not isinstance(value, list)
                or not value
                or not all(isinstance(v, str) and v for v in value)
                or len(set(value)) != len(value)
                or len(value) > 127
            ):
                raise ConfigError(str(path), key, f"must be a list of distinct phase names, got {value!r}")
        elif key not in ("mm_per_px", "pose_convention", "frames_planned") and not isinstance(value, str):
            raise ConfigError(str(path), key, f"must be a string, got {value!r}")
    return meta


def _profile_record(path: Path, value) -> dict[str, str]:
    """run.json's sensor_profile: "" (none: {}) or a recorded profile (``SensorProfile.record()``:
    TOML naming the profile's name, content hash and file), read as dataset/runs.py reads one."""
    if not isinstance(value, str):
        raise ConfigError(str(path), "sensor_profile", f'must be a recorded profile\'s text ("": none), got {value!r}')
    if not value.strip():
        return {}
    try:
        record = tomllib.loads(value)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(str(path), "sensor_profile", f"not a recorded profile (not valid TOML: {exc})") from None
    lacking = [key for key in ("name", "sha256", "file") if not isinstance(record.get(key), str)]
    if lacking:
        raise ConfigError(str(path), "sensor_profile", f"the recorded profile lacks {', '.join(lacking)}")
    return record


def imported_status(folder: Path, meta: dict) -> tuple[str, str]:
    """(status, reason) of the imported run: run.json's (default complete), so an aborted or
    interrupted run stays incomplete. ``running`` (exported while being written, or after its writer
    crashed) becomes ``aborted``: the imported file is closed, and no writer will continue it."""
    status, reason = meta.get("status", "complete"), meta.get("reason", "")
    if status == "running":
        return "aborted", (
            f"imported from {folder}, whose run.json says running (exported while being written, or after its "
            f"writer crashed){': ' + reason if reason else ''}"
        )
    if status != "complete" and not reason:
        reason = f"imported from {folder}: run.json says {status} and gives no reason"
    return status, reason


def planned_frames(folder: Path, meta: dict, rows: int) -> int:
    """run.json's frames_planned (default: the rows of frames.csv); never fewer than those rows."""
    planned = meta.get("frames_planned", rows)
    if planned < rows:
        raise ConfigError(
            str(folder / "run.json"), "frames_planned", f"is {planned}, fewer than the {rows} rows of frames.csv"
        )
    return planned


def imported_profile(folder: Path, meta: dict, given: str) -> str:
    """The sensor profile record the imported run keeps: ``--profile``'s (``given``), else run.json's
    (an exported run's own); both, and different: refused naming both (one is never put over the other)."""
    recorded = str(meta.get("sensor_profile", ""))
    if not given.strip() or not recorded.strip():
        return given if given.strip() else recorded
    mine, theirs = _profile_record(Path("--profile"), given), _profile_record(folder / "run.json", recorded)
    if mine["sha256"] != theirs["sha256"]:
        raise ConfigError(
            str(folder / "run.json"),
            "sensor_profile",
            f"is {theirs['name']} (sha256 {theirs['sha256'][:12]}…), but --profile gives {mine['name']} "
            f"(sha256 {mine['sha256'][:12]}…); leave out --profile to keep the run's, or remove sensor_profile "
            "from run.json to record the given one",
        )
    return given


def regular_file(path: Path) -> None:
    """RunFileError unless ``path`` is a regular file (a named pipe would block its read for ever)."""
    if not path.is_file():
        raise RunFileError(f"{path}: not a regular file (a named pipe, device or folder); expected a file")


def sensor_kind(folder: Path, meta: dict, option: str | None) -> str:
    """The sensor kind: ``--sensor``, else run.json's; one of SENSOR_KINDS, or a ConfigError that
    lists them (evaluate and the simulator need it; an unknown kind used to surface only there)."""
    if option is not None:
        if option not in SENSOR_KINDS:
            raise ConfigError(str(folder), "--sensor", f"must be one of {', '.join(SENSOR_KINDS)}, got {option!r}")
        return option
    kind = meta.get("sensor")
    if kind is None:
        raise ConfigError(
            str(folder / "run.json"),
            "sensor",
            f'missing: pass --sensor {"|".join(SENSOR_KINDS)} or put "sensor" in run.json '
            "(evaluate's physics row and the simulator need the kind)",
        )
    if kind not in SENSOR_KINDS:
        raise ConfigError(
            str(folder / "run.json"),
            "sensor",
            f"must be one of {', '.join(SENSOR_KINDS)}, got {kind!r}; pass --sensor to set it",
        )
    return str(kind)
