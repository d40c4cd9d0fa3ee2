"""Run files to and from plain folders, merging runs, and contact-sheet previews.

Folder format (what `dataset export` writes and `dataset import` reads):

    frames.csv      one row per frame: file, t_frame_s, Fx_N, Fy_N, Fz_N, Mx_Nmm, My_Nmm, Mz_Nmm,
                    x_mm, y_mm, z_mm, theta_deg (measured pose), and optionally the
                    commanded pose cx_mm, cy_mm, cz_mm, ctheta_deg, phase, level
    frames/*.png    the tactile frames, named in the CSV's ``file`` column (BGR as OpenCV reads PNG)
    object.png      the object's contact face (the condition image before placement)
    reference.png   optional: a no-contact frame (default: the first frame)
    run.json        optional: mm_per_px, object, sensor, protocol, capture_hz
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_file import RunFileError, RunHeader, RunWriter
from dataset.runs import open_run
from protocols.plan import PHASES
from common.table import finite_number
from common.errors import ConfigError

WRENCH_COLS = ("Fx_N", "Fy_N", "Fz_N", "Mx_Nmm", "My_Nmm", "Mz_Nmm")
POSE_COLS = ("x_mm", "y_mm", "z_mm", "theta_deg")
CMD_COLS = ("cx_mm", "cy_mm", "cz_mm", "ctheta_deg")


def export_run(path: str | Path, out: str | Path) -> int:
    out = Path(out)
    (out / "frames").mkdir(parents=True, exist_ok=True)
    with open_run(path) as f:
        n = f[S.FRAMES].shape[0]
        W, P, C = f[S.WRENCH][:n], f[S.POSE_MEASURED][:n], f[S.POSE_COMMANDED][:n]
        T, ph, lv = f[S.T_FRAME][:n], f[S.PHASE_INDEX][:n], f[S.LEVEL][:n]
        with open(out / "frames.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["file", "t_frame_s", *WRENCH_COLS, *POSE_COLS, *CMD_COLS, "phase", "level"])
            for i in range(n):
                name = f"frames/{i:06d}.png"
                cv2.imwrite(str(out / name), f[S.FRAMES][i])
                w.writerow([name, repr(float(T[i])), *(repr(float(v)) for v in W[i]), *(repr(float(v)) for v in P[i]),
                            *(repr(float(v)) for v in C[i]), PHASES[int(ph[i])], int(lv[i])])
        cv2.imwrite(str(out / "object.png"), f[S.OBJECT_IMAGE][()])
        cv2.imwrite(str(out / "reference.png"), f[S.REFERENCE_FRAME][()])
        a = f.attrs
        scale = float(a.get(S.ATTR_MM_PER_PX, float("nan")))
        meta = {"mm_per_px": scale if np.isfinite(scale) else None,  # null: uncalibrated (JSON has no NaN)
                "object": str(a.get(S.ATTR_OBJECT, "")),
                "sensor": str(a.get(S.ATTR_SENSOR_KIND, "")), "protocol": str(a.get(S.ATTR_PROTOCOL_NAME, "")),
                "capture_hz": float(a.get(S.ATTR_CAPTURE_HZ, 1.0)), "status": f[S.STATUS][()].decode()}
    (out / "run.json").write_text(json.dumps(meta, indent=2) + "\n")
    return n


def _read_image(path: Path, what: str) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise RunFileError(f"{path}: cannot read {what} (expected a PNG or JPEG image)")
    return img


# Bounds on imported numbers, each a reason away from any real tactile data: a NaN or a
# typo caught here never reaches a training set.
META_KEYS = ("mm_per_px", "object", "sensor", "protocol", "capture_hz", "status")
MM_PER_PX = (1e-4, 10.0)  # a GelSight Mini is 0.0634 mm/px at 320x240; beyond these no camera sees a gel
CAPTURE_HZ = (0.01, 1000.0)  # one frame a 100 s up to a fast camera's frame rate
POSE_LIMIT = 1e4  # mm or deg: 10 m of travel or ~28 turns; no lab stage goes further (as the rig config)
FORCE_N = 1e4  # |F|: 10 kN is far past crushing any tactile gel
TORQUE_NMM = 1e6  # |M|: 1 kN·m, likewise
T_FRAME_S = 1e8  # s: three years of recording
LEVEL = (0, 127)  # stored as int8 (acquisition/schema.py); 0 is "not at a depth level"


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
        elif key != "mm_per_px" and not isinstance(value, str):
            raise ConfigError(str(path), key, f"must be a string, got {value!r}")
    return meta


def _frame_path(folder: Path, table: Path, i: int, name: str | None) -> Path:
    """The frame file of CSV row ``i``; it must lie inside the import folder (no ``../``, no
    absolute path, no link out of it), so an import never reads files it was not given."""
    if not name:
        raise ConfigError(str(table), f"row {i + 2}, column file", "is empty (expected a path such as frames/000000.png)")
    candidate = (folder / name).resolve()
    if not candidate.is_relative_to(folder.resolve()):
        raise ConfigError(str(table), f"row {i + 2}, column file", f"{name!r} is outside {folder}; frame files must lie in "
                                                                  "the import folder")
    return candidate


def _read_rows(folder: Path, table: Path, rows: list[dict], capture_hz: float) -> list[tuple[Path, dict]]:
    """Every CSV row checked before anything is written: numbers finite and in range,
    phases known, levels whole, files inside the folder."""

    def number(row, col, i, default=None, *, bound=None, low=None, high=None):
        value = row.get(col, "")
        if value in ("", None):
            if default is None:
                raise RunFileError(f"{table}: row {i + 2}, column {col} is empty")
            return default
        try:
            parsed = float(value)
        except ValueError:
            raise RunFileError(f"{table}: row {i + 2}, column {col}: {value!r} is not a number") from None
        if bound is not None:
            low, high = -bound, bound
        return finite_number(str(table), f"row {i + 2}, column {col}", parsed, low=low, high=high)

    checked = []
    for i, row in enumerate(rows):
        pose = np.array([number(row, c, i, bound=POSE_LIMIT) for c in POSE_COLS])
        phase = row.get("phase") or "press"
        if phase not in PHASES:
            raise ConfigError(str(table), f"row {i + 2}, column phase", f"unknown phase {phase!r}; expected one of "
                                                                       f"{', '.join(PHASES)}")
        level = number(row, "level", i, default=0.0, low=LEVEL[0], high=LEVEL[1])
        if not float(level).is_integer():
            raise ConfigError(str(table), f"row {i + 2}, column level", f"must be a whole number, got {level!r}")
        checked.append((_frame_path(folder, table, i, row.get("file")), {
            S.WRENCH: np.array([number(row, c, i, bound=FORCE_N if c.endswith("_N") else TORQUE_NMM) for c in WRENCH_COLS]),
            S.POSE_COMMANDED: np.array([number(row, c, i, default=pose[k], bound=POSE_LIMIT)
                                        for k, c in enumerate(CMD_COLS)]),
            S.POSE_MEASURED: pose, S.T_FRAME: number(row, "t_frame_s", i, default=float(i), low=0.0, high=T_FRAME_S),
            S.T_CAPTURE: float(i) / capture_hz, S.WRENCH_SKEW: 0.0, S.CAPTURE_INDEX: i, S.STEP_INDEX: 0,
            S.PHASE_INDEX: PHASES.index(phase), S.LEVEL: int(level)}))
    return checked


def import_run(folder: str | Path, out: str | Path, *, mm_per_px: float | None = None, object_name: str | None = None) -> int:
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
            missing = [c for c in ("file", *WRENCH_COLS, *POSE_COLS) if c not in (reader.fieldnames or [])]
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
    checked = _read_rows(folder, table, rows, capture_hz)
    first = _read_image(checked[0][0], "the first frame")
    obj = _read_image(folder / "object.png", "the object image") if (folder / "object.png").exists() else None
    if obj is None:
        raise RunFileError(f"{folder}: no object.png (the object's contact face is the model's condition)")
    reference = _read_image(folder / "reference.png", "the reference frame") if (folder / "reference.png").exists() else first
    header = RunHeader(protocol_name=meta.get("protocol", "imported"), protocol_toml="", rig_config=f"imported from {folder}",
                       object_name=object_name or meta.get("object", "imported"), object_geometry="imported",
                       sensor_kind=meta.get("sensor", "unknown"), mm_per_px=float(scale),
                       capture_hz=capture_hz, frames_planned=len(rows),
                       contact_origin=(0.0, 0.0, 0.0, 0.0), phases=PHASES)
    writer = RunWriter.create(out, header, first.shape, cv2.resize(obj, first.shape[1::-1]), reference)
    try:
        for i, (frame_path, values) in enumerate(checked):
            img = first if i == 0 else _read_image(frame_path, f"frame {i}")
            if img.shape != first.shape:
                raise RunFileError(f"{frame_path}: {img.shape[1]}x{img.shape[0]} differs from the first frame's "
                                   f"{first.shape[1]}x{first.shape[0]}")
            writer.append(img, **values)
        writer.set_status("complete", "")
    except BaseException:
        writer.set_status("aborted", "import failed")
        raise
    finally:
        writer.close()
    return len(rows)


def merge_runs(paths: list[str | Path], out: str | Path) -> int:
    """One run file from several of one object, sensor and frame size; keeps each frame's source."""
    sources = [open_run(p) for p in paths]
    try:
        first = sources[0]
        keys = [(str(f.attrs.get(S.ATTR_OBJECT)), str(f.attrs.get(S.ATTR_SENSOR_KIND)), f[S.FRAMES].shape[1:])
                for f in sources]
        if len(set(keys)) > 1:
            detail = ", ".join(f"{p}: {k[0]}/{k[1]}/{k[2][1]}x{k[2][0]}" for p, k in zip(paths, keys))
            raise RunFileError(f"runs differ in object, sensor or frame size ({detail}); merge like with like")
        a = first.attrs
        total = sum(f[S.FRAMES].shape[0] for f in sources)
        header = RunHeader(protocol_name=str(a.get(S.ATTR_PROTOCOL_NAME, "")), protocol_toml=str(a.get(S.ATTR_PROTOCOL, "")),
                           rig_config="merged from: " + ", ".join(str(Path(p).resolve()) for p in paths),
                           object_name=keys[0][0], object_geometry=str(a.get(S.ATTR_OBJECT_GEOMETRY, "")),
                           sensor_kind=keys[0][1], mm_per_px=float(a.get(S.ATTR_MM_PER_PX, float("nan"))),
                           capture_hz=float(a.get(S.ATTR_CAPTURE_HZ, 1.0)), frames_planned=total,
                           contact_origin=tuple(a.get(S.ATTR_CONTACT_ORIGIN, (0, 0, 0, 0))), phases=PHASES)
        writer = RunWriter.create(out, header, keys[0][2], first[S.OBJECT_IMAGE][()], first[S.REFERENCE_FRAME][()])
        k = 0
        try:
            statuses = []
            for f in sources:
                statuses.append(f[S.STATUS][()].decode())
                for i in range(f[S.FRAMES].shape[0]):
                    row = {name: f[name][i] for name in (S.WRENCH, S.POSE_COMMANDED, S.POSE_MEASURED, S.T_FRAME,
                                                         S.T_CAPTURE, S.WRENCH_SKEW, S.STEP_INDEX, S.PHASE_INDEX, S.LEVEL)}
                    writer.append(f[S.FRAMES][i], **row, **{S.CAPTURE_INDEX: k})
                    k += 1
            bad = [f"{p}: {s}" for p, s in zip(paths, statuses) if s != "complete"]
            writer.set_status("complete" if not bad else "aborted", "; ".join(bad))
        finally:
            writer.close()
        return total
    finally:
        for f in sources:
            f.close()


def preview(path: str | Path, out: str | Path, *, tiles: int = 24, tile_px: int = 160) -> int:
    """A contact sheet of evenly spaced frames, each labelled with its frame index and wrench."""
    with open_run(path) as f:
        n = f[S.FRAMES].shape[0]
        if n == 0:
            raise RunFileError(f"{path}: no frames to preview")
        picks = np.unique(np.linspace(0, n - 1, min(tiles, n)).astype(int))
        images = []
        for i in picks:
            img = cv2.resize(f[S.FRAMES][i], (tile_px, tile_px), interpolation=cv2.INTER_AREA)
            w = f[S.WRENCH][i]
            for line, text in enumerate((f"#{i}", f"F {w[0]:+.2f} {w[1]:+.2f} {w[2]:+.2f} N",
                                         f"M {w[3]:+.0f} {w[4]:+.0f} {w[5]:+.1f} Nmm")):
                cv2.putText(img, text, (4, 14 + 14 * line), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (255, 255, 255), 1, cv2.LINE_AA)
            images.append(img)
    cols = 6
    while len(images) % cols:
        images.append(np.zeros_like(images[0]))
    sheet = np.vstack([np.hstack(images[r:r + cols]) for r in range(0, len(images), cols)])
    cv2.imwrite(str(out), sheet)
    return len(picks)
