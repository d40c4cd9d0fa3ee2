"""Run files to and from plain folders (merging: dataset/merge.py, previews: dataset/preview.py).

Folder format (what `dataset export` writes and `dataset import` reads):

    frames.csv      one row per frame: ``file``, then the columns of every per-frame field
                    of the run-file table (acquisition/schema.py, ``columns_of``):
                    t_frame_s, Fx_N Fy_N Fz_N Mx_Nmm My_Nmm Mz_Nmm, x_mm y_mm z_mm theta_deg
                    (measured pose), cx_mm cy_mm cz_mm ctheta_deg (commanded), t_capture_s,
                    wrench_skew_s, capture_index, step_index, phase (by name), level, and any
                    field added since. Import needs file, the wrench and the measured pose;
                    a field without its columns gets a default (below) or its table fill.
    frames/*.png    the tactile frames, named in the CSV's ``file`` column (BGR as OpenCV reads PNG)
    object.png      the object's contact face (the condition image before placement)
    reference.png   optional: a no-contact frame (default: the first frame)
    wrench_stream.csv  optional: the gauge's full-rate wrench, t_s then the six components
    run.json        optional: mm_per_px, object, sensor, protocol, capture_hz, status, phases
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_file import RunFileError, RunHeader, RunWriter
from acquisition.run_layout import decode_phases, phase_names
from common.errors import ConfigError
from common.table import finite_number
from dataset.merge import merge_runs  # noqa: F401 (merge and preview, long exported from here)
from dataset.preview import preview  # noqa: F401
from dataset.runs import open_run, read
from protocols.plan import PHASES

FIELDS = {f.path: f for f in S.PER_FRAME_FIELDS}
WRENCH_COLS = S.columns_of(FIELDS[S.WRENCH])
POSE_COLS = S.columns_of(FIELDS[S.POSE_MEASURED])
CMD_COLS = S.columns_of(FIELDS[S.POSE_COMMANDED])
LEADING = (S.T_FRAME, S.WRENCH, S.POSE_MEASURED)  # first in the CSV: what a person reads first
REQUIRED = (S.WRENCH, S.POSE_MEASURED)  # an import without these columns has nothing to train on
DERIVED = (S.CAPTURE_INDEX,)  # the imported file's own capture grid: 0, 1, 2, ... (never read)
STREAM_CSV = "wrench_stream.csv"
STREAM_COLS = ("t_s", *WRENCH_COLS)
# run.json key → the root attribute it carries ("status" is the run/status dataset)
META = {
    "mm_per_px": S.ATTR_MM_PER_PX,
    "object": S.ATTR_OBJECT,
    "sensor": S.ATTR_SENSOR_KIND,
    "protocol": S.ATTR_PROTOCOL_NAME,
    "capture_hz": S.ATTR_CAPTURE_HZ,
    "phases": S.ATTR_PHASES,
}


def csv_fields() -> list[S.Field]:
    """The per-frame fields in frames.csv order: LEADING, then the rest of the table."""
    return [FIELDS[p] for p in LEADING] + [f for f in S.PER_FRAME_FIELDS if f.path not in LEADING]


def _cell(value, field: S.Field) -> str:
    return str(int(value)) if np.dtype(field.dtype).kind in "iu" else repr(float(value))


def export_run(path: str | Path, out: str | Path) -> int:
    """frames/*.png, frames.csv (every per-frame field of the table the file has), object.png,
    reference.png, wrench_stream.csv (when recorded) and run.json in ``out``; the frame count."""
    out = Path(out)
    (out / "frames").mkdir(parents=True, exist_ok=True)
    with open_run(path) as f:
        n = min(f[S.FRAMES].shape[0], *(f[fl.path].shape[0] for fl in S.PER_FRAME_FIELDS if fl.path in f))
        fields = [fl for fl in csv_fields() if fl.path in f]
        values = {fl.path: read(f, fl.path, slice(0, n)) for fl in fields}
        if S.PHASE_INDEX in values:  # by name, through the file's own phases
            values[S.PHASE_INDEX] = np.array(phase_names(f, values[S.PHASE_INDEX]), dtype=object)
        with open(out / "frames.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["file", *(c for fl in fields for c in S.columns_of(fl))])
            for i in range(n):
                name = f"frames/{i:06d}.png"
                cv2.imwrite(str(out / name), read(f, S.FRAMES, i))
                cells = [name]
                for fl in fields:
                    v = values[fl.path][i]
                    cells += [v] if fl.path == S.PHASE_INDEX else [_cell(x, fl) for x in np.atleast_1d(v)]
                w.writerow(cells)
        if S.WRENCH_STREAM in f and f[S.WRENCH_STREAM].shape[0]:
            with open(out / STREAM_CSV, "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(STREAM_COLS)
                w.writerows([repr(float(x)) for x in r] for r in read(f, S.WRENCH_STREAM))
        cv2.imwrite(str(out / "object.png"), f[S.OBJECT_IMAGE][()])
        cv2.imwrite(str(out / "reference.png"), f[S.REFERENCE_FRAME][()])
        a = f.attrs
        scale = float(a.get(S.ATTR_MM_PER_PX, float("nan")))
        meta = {
            "mm_per_px": scale if np.isfinite(scale) else None,  # null: uncalibrated (JSON has no NaN)
            "object": str(a.get(S.ATTR_OBJECT, "")),
            "sensor": str(a.get(S.ATTR_SENSOR_KIND, "")),
            "protocol": str(a.get(S.ATTR_PROTOCOL_NAME, "")),
            "capture_hz": float(a.get(S.ATTR_CAPTURE_HZ, 1.0)),
            "status": f[S.STATUS][()].decode(),
            "phases": list(decode_phases(f)),
        }
    (out / "run.json").write_text(json.dumps(meta, indent=2) + "\n")
    return n


def _read_image(path: Path, what: str) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise RunFileError(f"{path}: cannot read {what} (expected a PNG or JPEG image)")
    return img


# Bounds on imported numbers, each a reason away from any real tactile data: a NaN or a
# typo caught here never reaches a training set.
META_KEYS = ("mm_per_px", "object", "sensor", "protocol", "capture_hz", "status", "phases")
MM_PER_PX = (1e-4, 10.0)  # a GelSight Mini is 0.0634 mm/px at 320x240; beyond these no camera sees a gel
CAPTURE_HZ = (0.01, 1000.0)  # one frame a 100 s up to a fast camera's frame rate
POSE_LIMIT = 1e4  # mm or deg: 10 m of travel or ~28 turns; no lab stage goes further (as the rig config)
FORCE_N = 1e4  # |F|: 10 kN is far past crushing any tactile gel
TORQUE_NMM = 1e6  # |M|: 1 kN·m, likewise
T_FRAME_S = 1e8  # s: three years of recording
LEVEL = (0, 127)  # stored as int8 (acquisition/schema.py); 0 is "not at a depth level"
# (low, high) per field (per column for the wrench); a field not listed (one added to the
# table later) is checked finite and, for whole-number dtypes, whole and within its dtype
BOUNDS: dict[str, Any] = {
    S.WRENCH: [(-FORCE_N, FORCE_N)] * 3 + [(-TORQUE_NMM, TORQUE_NMM)] * 3,
    S.POSE_MEASURED: (-POSE_LIMIT, POSE_LIMIT),
    S.POSE_COMMANDED: (-POSE_LIMIT, POSE_LIMIT),
    S.T_FRAME: (0.0, T_FRAME_S),
    S.T_CAPTURE: (0.0, T_FRAME_S),
    S.WRENCH_SKEW: (0.0, T_FRAME_S),
    S.LEVEL: LEVEL,
}


def _read_meta(folder: Path) -> dict:
    """run.json checked key by key; ConfigError names the file, the key and the value."""
    path = folder / "run.json"
    if not path.exists():
        return {}
    try:
        meta = json.loads(path.read_text())
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
        elif key == "phases":
            if (
                not isinstance(value, list)
                or not value
                or not all(isinstance(v, str) and v for v in value)
                or len(set(value)) != len(value)
                or len(value) > 127
            ):
                raise ConfigError(str(path), key, f"must be a list of distinct phase names, got {value!r}")
        elif key != "mm_per_px" and not isinstance(value, str):
            raise ConfigError(str(path), key, f"must be a string, got {value!r}")
    return meta


def _frame_path(folder: Path, table: Path, i: int, name: str | None) -> Path:
    """The frame file of CSV row ``i``; it must lie inside the import folder (no ``../``, no
    absolute path, no link out of it), so an import never reads files it was not given."""
    if not name:
        raise ConfigError(
            str(table), f"row {i + 2}, column file", "is empty (expected a path such as frames/000000.png)"
        )
    candidate = (folder / name).resolve()
    if not candidate.is_relative_to(folder.resolve()):
        raise ConfigError(
            str(table),
            f"row {i + 2}, column file",
            f"{name!r} is outside {folder}; frame files must lie in the import folder",
        )
    return candidate


def _number(table: Path, row: dict, col: str, i: int, default=None, *, low=None, high=None, integer=False):
    value = row.get(col, "")
    if value in ("", None):
        if default is None:
            raise RunFileError(f"{table}: row {i + 2}, column {col} is empty")
        return default
    try:
        parsed = float(value)
    except ValueError:
        raise RunFileError(f"{table}: row {i + 2}, column {col}: {value!r} is not a number") from None
    key = f"row {i + 2}, column {col}"
    parsed = finite_number(str(table), key, parsed, low=low, high=high)
    if integer and not float(parsed).is_integer():
        raise ConfigError(str(table), key, f"must be a whole number, got {parsed!r}")
    return parsed


def _field_value(table: Path, field: S.Field, row: dict, i: int, default) -> np.ndarray | float | int:
    """One field of CSV row ``i``, checked: finite, within BOUNDS (or its dtype), whole for
    whole-number dtypes; ``default`` (an array or scalar) where its cells are absent."""
    cols = S.columns_of(field)
    kind = np.dtype(field.dtype).kind
    limits = BOUNDS.get(field.path)
    if limits is None and kind in "iu":
        limits = (float(np.iinfo(field.dtype).min), float(np.iinfo(field.dtype).max))
    per_col = limits if isinstance(limits, list) else [limits or (None, None)] * len(cols)
    fallback = (
        [None] * len(cols) if default is None else np.broadcast_to(np.asarray(default, dtype=float), (len(cols),))
    )
    got = [
        _number(table, row, c, i, None if d is None else float(d), low=lo, high=hi, integer=kind in "iu")
        for c, d, (lo, hi) in zip(cols, fallback, per_col)
    ]
    out = np.asarray(got, dtype=field.dtype)
    return out if field.shape else out[0].item()


def _read_rows(
    folder: Path, table: Path, rows: list[dict], capture_hz: float, phases: tuple[str, ...]
) -> list[tuple[Path, dict]]:
    """Every CSV row checked before anything is written: numbers finite and in range,
    phases among the file's, levels whole, files inside the folder."""
    checked = []
    for i, row in enumerate(rows):
        phase = row.get("phase") or "press"
        if phase not in phases:
            raise ConfigError(
                str(table),
                f"row {i + 2}, column phase",
                f"unknown phase {phase!r}; expected one of {', '.join(phases)}",
            )
        values: dict = {S.PHASE_INDEX: phases.index(phase), S.CAPTURE_INDEX: i}
        defaults = {S.T_FRAME: float(i), S.T_CAPTURE: float(i) / capture_hz, S.LEVEL: 0.0}
        for field in csv_fields():
            if field.path in (S.PHASE_INDEX, *DERIVED):
                continue
            if field.path == S.POSE_COMMANDED:  # absent: the stages were where they were told
                default = values[S.POSE_MEASURED]
            else:
                default = defaults.get(field.path, None if field.path in REQUIRED else field.fill)
            values[field.path] = _field_value(table, field, row, i, default)
        checked.append((_frame_path(folder, table, i, row.get("file")), values))
    return checked


def _read_stream(folder: Path) -> np.ndarray | None:
    """wrench_stream.csv, checked like frames.csv (finite, in the wrench's bounds, time not going back)."""
    path = folder / STREAM_CSV
    if not path.exists():
        return None
    try:
        with open(path, newline="") as fh:
            reader = csv.DictReader(fh)
            missing = [c for c in STREAM_COLS if c not in (reader.fieldnames or [])]
            if missing:
                raise RunFileError(f"{path}: missing column(s) {', '.join(missing)}")
            rows = list(reader)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise RunFileError(f"{path}: not a readable CSV table ({exc})") from None
    limits = [(0.0, T_FRAME_S), *BOUNDS[S.WRENCH]]
    out = np.array(
        [
            [_number(path, r, c, i, low=lo, high=hi) for c, (lo, hi) in zip(STREAM_COLS, limits)]
            for i, r in enumerate(rows)
        ],
        dtype=float,
    ).reshape(-1, len(STREAM_COLS))
    back = np.diff(out[:, 0]) < 0
    if back.any():
        raise ConfigError(str(path), f"row {int(np.argmax(back)) + 3}, column t_s", "goes back in time")
    return out


def import_run(
    folder: str | Path, out: str | Path, *, mm_per_px: float | None = None, object_name: str | None = None
) -> int:
    """A run file from a folder in the export format. Every number, phase and file name is
    checked before the run file is created; ConfigError or RunFileError name the file, the
    row or key, and the value."""
    folder = Path(folder)
    table = folder / "frames.csv"
    if not table.exists():
        raise RunFileError(f"{folder}: no frames.csv (see docs/dataset.md for the folder format)")
    meta = _read_meta(folder)
    try:
        with open(table, newline="") as fh:
            reader = csv.DictReader(fh)
            need = ("file", *(c for p in REQUIRED for c in S.columns_of(FIELDS[p])))
            missing = [c for c in need if c not in (reader.fieldnames or [])]
            if missing:
                raise RunFileError(f"{table}: missing column(s) {', '.join(missing)}")
            rows = list(reader)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise RunFileError(f"{table}: not a readable CSV table ({exc})") from None
    if not rows:
        raise RunFileError(f"{table}: no rows")
    if mm_per_px is not None:
        scale = finite_number(str(folder), "--mm-per-px", mm_per_px, low=MM_PER_PX[0], high=MM_PER_PX[1])
    elif meta.get("mm_per_px") is not None:
        scale = meta["mm_per_px"]
    else:
        raise RunFileError(f"{folder}: mm per pixel unknown: pass --mm-per-px or put mm_per_px in run.json")
    capture_hz = float(meta.get("capture_hz", 1.0))
    # A folder from another rig names phases in the standard vocabulary; an exported run
    # brings its own list, in its own order.
    phases = tuple(meta.get("phases") or PHASES)
    checked = _read_rows(folder, table, rows, capture_hz, phases)
    stream = _read_stream(folder)
    first = _read_image(checked[0][0], "the first frame")
    obj = _read_image(folder / "object.png", "the object image") if (folder / "object.png").exists() else None
    if obj is None:
        raise RunFileError(f"{folder}: no object.png (the object's contact face is the model's condition)")
    reference = (
        _read_image(folder / "reference.png", "the reference frame") if (folder / "reference.png").exists() else first
    )
    header = RunHeader(
        protocol_name=meta.get("protocol", "imported"),
        protocol_toml="",
        rig_config=f"imported from {folder}",
        object_name=object_name or meta.get("object", "imported"),
        object_geometry="imported",
        sensor_kind=meta.get("sensor", "unknown"),
        mm_per_px=float(scale),
        capture_hz=capture_hz,
        frames_planned=len(rows),
        contact_origin=(0.0, 0.0, 0.0, 0.0),
        phases=phases,
    )
    writer = RunWriter.create(out, header, first.shape, cv2.resize(obj, first.shape[1::-1]), reference)
    try:
        for i, (frame_path, values) in enumerate(checked):
            img = first if i == 0 else _read_image(frame_path, f"frame {i}")
            if img.shape != first.shape:
                raise RunFileError(
                    f"{frame_path}: {img.shape[1]}x{img.shape[0]} differs from the first frame's "
                    f"{first.shape[1]}x{first.shape[0]}"
                )
            writer.append(img, stream=stream if i == 0 else None, **values)
        writer.set_status("complete", "")
    except BaseException:
        writer.set_status("aborted", "import failed")
        raise
    finally:
        writer.close()
    return len(rows)
