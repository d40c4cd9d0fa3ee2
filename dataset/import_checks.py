"""The import folder's format and its checks: frames.csv row by row (run.json: dataset/import_meta.py).

Everything here runs before a run file is created, and the run file itself is written whole or
not at all (acquisition/whole_run.py), so a refused import writes nothing. Each error names the
file, the row and column (or the run.json key) and the value. frames.csv is strict: read with or
without a byte-order mark, every column known (``file``, the columns of the run-file table) or
named in ``--ignore-columns``, every row with a cell for every column and none empty. A column
absent from the header altogether takes the default the format documents (docs/dataset.md),
and the import says which.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np

from acquisition import schema as S
from acquisition.run_checks import row_findings
from acquisition.run_file import RunFileError
from common.errors import ConfigError
from common.table import finite_number
from dataset.import_meta import regular_file

FIELDS = {f.path: f for f in S.PER_FRAME_FIELDS}
WRENCH_COLS = S.columns_of(FIELDS[S.WRENCH])
POSE_COLS = S.columns_of(FIELDS[S.POSE_MEASURED])
CMD_COLS = S.columns_of(FIELDS[S.POSE_COMMANDED])
LEADING = (S.T_FRAME, S.WRENCH, S.POSE_MEASURED)  # first in the CSV: what a person reads first
REQUIRED = (S.WRENCH, S.POSE_MEASURED)  # an import without these columns has nothing to train on
DERIVED = (S.CAPTURE_INDEX,)  # the imported file's own capture grid: 0, 1, 2, ... (never read)
POSES = (S.POSE_MEASURED, S.POSE_COMMANDED)  # converted by the folder's pose_convention
STREAM_CSV = "wrench_stream.csv"
STREAM_COLS = ("t_s", *WRENCH_COLS)


def csv_fields() -> list[S.Field]:
    """The per-frame fields in frames.csv order: LEADING, then the rest of the table."""
    return [FIELDS[p] for p in LEADING] + [f for f in S.PER_FRAME_FIELDS if f.path not in LEADING]


# Bounds on imported numbers, each a reason away from any real tactile data: a NaN or a
# typo caught here never reaches a training set (run.json's: dataset/import_meta.py).
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


def row_order(table: Path, checked: list[tuple[Path, dict]], phases: tuple[str, ...]) -> None:
    """The rows as every reader of the run file will check them (acquisition/run_checks.py's
    ``row_findings``: time increasing, the capture grid, phases, levels, finite numbers), before
    anything is written; RunFileError naming frames.csv, the column and the row."""
    values = [v for _, v in checked]
    rows = {name: np.stack([np.asarray(v[name]) for v in values]) for name in values[0]}
    findings = row_findings(rows, len(values), len(phases), where=lambda i: f"row {i + 2}")
    if findings:
        more = f" (and {len(findings) - 1} more)" if len(findings) > 1 else ""
        raise RunFileError(f"{table}: {findings[0]}{more}; every reader of the run file would refuse it")


def frame_path(folder: Path, table: Path, i: int, name: str | None) -> Path:
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


def number(table: Path, row: dict, col: str, i: int, default=None, *, low=None, high=None, integer=False):
    """Row ``i``'s cell in column ``col``, checked; ``default`` only when the table has no such
    column at all (an empty cell in a column it has is an error: nothing is filled in per row)."""
    if col not in row:
        if default is None:
            raise RunFileError(f"{table}: no column {col} (required)")
        return default
    value = row[col]
    if value in ("", None):
        raise RunFileError(f"{table}: row {i + 2}, column {col} is empty; every row needs a value in every column")
    try:
        parsed = float(value)
    except ValueError:
        raise RunFileError(f"{table}: row {i + 2}, column {col}: {value!r} is not a number") from None
    key = f"row {i + 2}, column {col}"
    parsed = finite_number(str(table), key, parsed, low=low, high=high)
    if integer and not float(parsed).is_integer():
        raise ConfigError(str(table), key, f"must be a whole number, got {parsed!r}")
    return parsed


def field_value(table: Path, field: S.Field, row: dict, i: int, default) -> np.ndarray | float | int:
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
        number(table, row, c, i, None if d is None else float(d), low=lo, high=hi, integer=kind in "iu")
        for c, d, (lo, hi) in zip(cols, fallback, per_col)
    ]
    out = np.asarray(got, dtype=field.dtype)
    return out if field.shape else out[0].item()


def read_rows(
    folder: Path, table: Path, rows: list[dict], capture_hz: float, phases: tuple[str, ...], signs: np.ndarray
) -> list[tuple[Path, dict]]:
    """Every CSV row checked before anything is written: numbers finite and in range,
    phases among the file's, levels whole, files inside the folder; poses times ``signs``
    (dataset/pose_convention.py: the folder's convention brought to the run file's)."""
    checked = []
    for i, row in enumerate(rows):
        phase = row.get("phase", "press")  # a table without the column: press (docs/dataset.md)
        if not phase:
            raise ConfigError(
                str(table), f"row {i + 2}, column phase", "is empty; expected one of " + ", ".join(phases)
            )
        if phase not in phases:
            raise ConfigError(
                str(table),
                f"row {i + 2}, column phase",
                f"unknown phase {phase!r}; expected one of {', '.join(phases)}",
            )
        values: dict = {S.PHASE_INDEX: phases.index(phase), S.CAPTURE_INDEX: i}
        if S.CAPTURE_INDEX in row:  # the imported file's grid is the row number: a column must say the same
            given = number(table, row, S.CAPTURE_INDEX, i, integer=True)
            if given != i:
                raise ConfigError(
                    str(table),
                    f"row {i + 2}, column {S.CAPTURE_INDEX}",
                    f"is {given:g}, expected {i} (the row's number)",
                )
        defaults = {S.T_FRAME: float(i), S.T_CAPTURE: float(i) / capture_hz, S.LEVEL: 0.0}
        for field in csv_fields():
            if field.path in (S.PHASE_INDEX, *DERIVED):
                continue
            if field.path == S.POSE_COMMANDED:  # absent: the stages were where they were told
                default = values[S.POSE_MEASURED] * signs  # (in the folder's convention, like the cells)
            else:
                default = defaults.get(field.path, None if field.path in REQUIRED else field.fill)
            values[field.path] = field_value(table, field, row, i, default)
            if field.path in POSES:
                values[field.path] = values[field.path] * signs
        checked.append((frame_path(folder, table, i, row.get("file")), values))
    return checked


def read_stream(folder: Path) -> np.ndarray | None:
    """wrench_stream.csv, checked like frames.csv (finite, in the wrench's bounds, time not going back)."""
    path = folder / STREAM_CSV
    if not path.exists():
        return None
    header, rows = _strict_rows(path, STREAM_COLS, ())
    missing = [c for c in STREAM_COLS if c not in header]
    if missing:
        raise RunFileError(f"{path}: missing column(s) {', '.join(missing)}")
    limits = [(0.0, T_FRAME_S), *BOUNDS[S.WRENCH]]
    out = np.array(
        [
            [number(path, r, c, i, low=lo, high=hi) for c, (lo, hi) in zip(STREAM_COLS, limits)]
            for i, r in enumerate(rows)
        ],
        dtype=float,
    ).reshape(-1, len(STREAM_COLS))
    back = np.diff(out[:, 0]) < 0
    if back.any():
        raise ConfigError(str(path), f"row {int(np.argmax(back)) + 3}, column t_s", "goes back in time")
    return out


def known_columns() -> tuple[str, ...]:
    """Every column frames.csv may have: ``file`` and the columns of the run-file table's per-frame fields."""
    return ("file", *(c for f in csv_fields() for c in S.columns_of(f)))


def _strict_rows(path: Path, known: tuple[str, ...], ignore: tuple[str, ...]) -> tuple[list[str], list[dict]]:
    """(header, rows) of a CSV table (UTF-8, with or without a byte-order mark), strictly: no column
    outside ``known`` unless in ``ignore`` (then dropped), no column twice, every row with exactly a
    cell per column."""
    regular_file(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header = next(reader, None)
            if header is None:
                raise RunFileError(f"{path}: empty (expected a header row of column names)")
            header = [c.strip() for c in header]
            table = [(i, cells) for i, cells in enumerate(reader) if cells]
    except (UnicodeDecodeError, csv.Error) as exc:
        raise RunFileError(f"{path}: not a readable UTF-8 CSV table ({exc})") from None
    twice = sorted({c for c in header if header.count(c) > 1})
    if twice:
        raise RunFileError(f"{path}: column(s) {', '.join(twice)} appear more than once in the header")
    not_there = [c for c in ignore if c not in header]
    if not_there:
        raise RunFileError(
            f"{path}: --ignore-columns {', '.join(not_there)}: no such column (it has {', '.join(header)})"
        )
    unknown = [c for c in header if c not in known and c not in ignore]
    if unknown:
        raise RunFileError(
            f"{path}: unknown column(s) {', '.join(unknown)}; expected only {', '.join(known)} "
            "(docs/dataset.md), or name them in --ignore-columns to import without them"
        )
    rows = []
    for i, cells in table:
        if len(cells) != len(header):
            missing = header[len(cells) :]
            detail = f"missing {', '.join(missing)}" if missing else f"{len(cells) - len(header)} extra"
            raise RunFileError(
                f"{path}: row {i + 2} has {len(cells)} cells, the header {len(header)} ({detail}); "
                "every row needs a cell for every column"
            )
        rows.append({c: v for c, v in zip(header, cells) if c not in ignore})
    return [c for c in header if c not in ignore], rows


def absent_columns(header: list[str]) -> list[str]:
    """The optional per-frame fields frames.csv has no column for, each with the default it takes."""
    defaults = {
        S.T_FRAME: "the row number (s)",
        S.T_CAPTURE: "row number / capture_hz",
        S.POSE_COMMANDED: "the measured pose",
        S.PHASE_INDEX: "press",
        S.LEVEL: "0",
    }
    out = []
    for f in csv_fields():
        if f.path in REQUIRED or f.path in DERIVED or any(c in header for c in S.columns_of(f)):
            continue
        out.append(
            f"{'/'.join(S.columns_of(f)) if len(S.columns_of(f)) < 3 else S.columns_of(f)[0] + '…'} = "
            f"{defaults.get(f.path, f'{f.fill:g} (the table fill)')}"
        )
    return out


def read_table(folder: Path, ignore: tuple[str, ...] = ()) -> tuple[Path, list[str], list[dict]]:
    """frames.csv: its header (without ``ignore``d columns) and rows, strictly (``_strict_rows``),
    with the columns an import needs (the file, the wrench, the measured pose)."""
    table = folder / "frames.csv"
    if not table.exists():
        raise RunFileError(f"{folder}: no frames.csv (see docs/dataset.md for the folder format)")
    header, rows = _strict_rows(table, known_columns(), ignore)
    need = ("file", *(c for p in REQUIRED for c in S.columns_of(FIELDS[p])))
    missing = [c for c in need if c not in header]
    if missing:
        raise RunFileError(f"{table}: missing column(s) {', '.join(missing)}")
    for f in csv_fields():
        cols = S.columns_of(f)
        have = [c for c in cols if c in header]
        if have and len(have) < len(cols):
            raise RunFileError(
                f"{table}: has {', '.join(have)} but not {', '.join(c for c in cols if c not in header)}; "
                f"give all of {f.path}'s columns or none"
            )
    if not rows:
        raise RunFileError(f"{table}: no rows")
    return table, header, rows
