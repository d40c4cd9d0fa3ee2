"""The presses ``rig sensor calibrate`` fits: from a folder of PNGs or from a run file.

A folder: a no-contact frame (``background.png`` or ``--background``) and press PNGs (all the
others, or those a CSV lists). The CSV's ``file`` column names each press; the optional
columns ``centre_x_px``, ``centre_y_px``, ``radius_px`` (manual contact override), ``depth_mm``
and ``ball_radius_mm`` set what is known about it (blank: found automatically / the command's).

A run file recorded with a sphere: its reference frame is the background; press frames (the
press phase, no shear or twist) are chosen spread over depth, each depth known from z of
``pose_measured``, the ball radius from the object and the scale from the file.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

OVERRIDES = ("centre_x_px", "centre_y_px", "radius_px", "depth_mm", "ball_radius_mm")
MIN_DEPTH_MM = 0.1  # shallower presses change too few pixels to fit
STILL_MM, STILL_DEG = 0.01, 0.05  # a press frame: x, y and θ at the contact point


@dataclass
class PressSet:
    background: np.ndarray
    presses: list  # sensor_sim.calibration.Press
    mm_per_px: float | None  # known from the source (a run file), else None
    source: str  # one line: where the frames came from
    notes: list[str] = field(default_factory=list)  # what a person should know (ignored columns, ...)


def _read(path: Path, what: str) -> np.ndarray:
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise ValueError(f"{path}: cannot read the {what} as an image")
    return img


def _number(path: Path, row: int, key: str, text: str) -> float | None:
    if text is None or not text.strip():
        return None
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{path}: row {row}, {key}: expected a number, got {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise ValueError(f"{path}: row {row}, {key}: expected a finite number >= 0, got {text!r}")
    return value


def from_folder(folder: Path, ball_radius_mm: float | None, background: Path | None, table: Path | None) -> PressSet:
    from sensor_sim.calibration import Press

    bg_path = background or folder / "background.png"
    if not bg_path.is_file():
        raise ValueError(f"{bg_path}: no no-contact frame; name it background.png or pass --background FILE")
    bg = _read(bg_path, "background")
    table = table or (folder / "presses.csv" if (folder / "presses.csv").is_file() else None)
    notes: list[str] = []
    presses = []
    if table is None:
        files = sorted(p for p in folder.glob("*.png") if p.resolve() != bg_path.resolve())
        rows = [{"file": p.name} for p in files]
        notes.append(f"{len(rows)} press PNGs in {folder} (no CSV: every contact found automatically)")
    else:
        with open(table, newline="") as fh:
            reader = csv.DictReader(fh)
            columns = reader.fieldnames or []
            rows = list(reader)
        if "file" not in columns:
            raise ValueError(f"{table}: needs a 'file' column naming each press PNG; has {', '.join(columns)}")
        ignored = [c for c in columns if c not in ("file", *OVERRIDES)]
        used = [c for c in columns if c in OVERRIDES]
        notes.append(
            f"{len(rows)} presses listed in {table}; "
            + (f"overrides from columns {', '.join(used)}" if used else "no override columns: contacts found")
            + (f"; ignored columns {', '.join(ignored)} (known: {', '.join(OVERRIDES)})" if ignored else "")
        )
    for i, row in enumerate(rows, start=2):
        where = table or folder
        values = {k: _number(Path(where), i, k, row.get(k, "")) for k in OVERRIDES}
        radius = values["ball_radius_mm"] or ball_radius_mm
        if radius is None:
            raise ValueError(f"{row['file']}: ball radius unknown: pass --ball-radius-mm or a ball_radius_mm column")
        cx, cy = values["centre_x_px"], values["centre_y_px"]
        if (cx is None) != (cy is None):
            raise ValueError(f"{where}: row {i}: give both centre_x_px and centre_y_px, or neither")
        presses.append(
            Press(
                _read(folder / row["file"], "press"),
                radius,
                centre_px=(cx, cy) if cx is not None and cy is not None else None,
                radius_px=values["radius_px"],
                depth_mm=values["depth_mm"],
                name=row["file"],
            )
        )
    return PressSet(bg, presses, None, f"{len(presses)} presses from {folder}", notes)


def from_run(path: Path, count: int, ball_radius_mm: float | None) -> PressSet:
    """``count`` press frames of a run file, spread over depth (see the module docstring)."""
    from acquisition import schema as S
    from acquisition.run_reader import RunReader
    from objects.indenters import INDENTERS, get_indenter
    from sensor_sim.calibration import Press

    with RunReader.open(path) as f:  # verified: a damaged or malformed file is one RunFileError line
        obj = f.text(S.ATTR_OBJECT)
        mm_per_px = f.number(S.ATTR_MM_PER_PX)
        background = f.image(S.REFERENCE_FRAME)
        poses = f.rows[S.POSE_MEASURED]
        phases = [f.phases[int(k)] for k in f.rows[S.PHASE_INDEX]]
        if ball_radius_mm is None:
            if not (obj.startswith("sphere") and obj in INDENTERS):
                raise ValueError(f"{path}: object {obj!r} is not a library sphere: pass --ball-radius-mm")
            ball_radius_mm = get_indenter(obj).radius_mm
        if not (math.isfinite(mm_per_px) and mm_per_px > 0):
            raise ValueError(f"{path}: attribute {S.ATTR_MM_PER_PX} is {mm_per_px}: pass --mm-per-px")
        depth = -poses[:, 2]
        still = (np.abs(poses[:, 0]) < STILL_MM) & (np.abs(poses[:, 1]) < STILL_MM) & (np.abs(poses[:, 3]) < STILL_DEG)
        ok = np.flatnonzero(still & (depth >= MIN_DEPTH_MM) & np.array([p == "press" for p in phases], bool))
        if len(ok) < 1:
            raise ValueError(f"{path}: no press frame {MIN_DEPTH_MM} mm or deeper without shear or twist")
        targets = np.linspace(depth[ok].min(), depth[ok].max(), min(count, len(ok)))
        chosen = sorted({int(ok[np.argmin(np.abs(depth[ok] - t))]) for t in targets})
        presses = [
            Press(
                f.frame(k),
                float(ball_radius_mm),
                depth_mm=float(depth[k]),
                name=f"frame {k} ({depth[k]:.2f} mm)",
            )
            for k in chosen
        ]
    note = f"{len(presses)} press frames of {len(ok)} in {path} ({obj}, radius {ball_radius_mm:g} mm)"
    return PressSet(background, presses, mm_per_px, f"{len(presses)} press frames of {path}", [note])
