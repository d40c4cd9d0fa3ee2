"""Run files to and from plain folders (merging: dataset/merge.py, previews: dataset/preview.py).

Folder format (what `dataset export` writes and `dataset import` reads; docs/dataset.md has the
table of what import accepts):

    frames.csv      one row per frame: ``file``, then the columns of every per-frame field
                    of the run-file table (acquisition/schema.py, ``columns_of``):
                    t_frame_s, Fx_N Fy_N Fz_N Mx_Nmm My_Nmm Mz_Nmm, x_mm y_mm z_mm theta_deg
                    (measured pose), cx_mm cy_mm cz_mm ctheta_deg (commanded), t_capture_s,
                    wrench_skew_s, capture_index, step_index, phase (by name), level, and any
                    field added since. Import needs file, the wrench and the measured pose;
                    a field without its columns gets a default (below) or its table fill.
    frames/*.png    the tactile frames, named in the CSV's ``file`` column (BGR as OpenCV reads PNG);
                    square, or import says --crop or --pad (dataset/import_images.py)
    object.png      the object's contact face centred at pose 0, spanning the frames' field of view
    reference.png   optional: a no-contact frame (default: the first frame)
    wrench_stream.csv  optional: the gauge's full-rate wrench, t_s then the six components
    run.json        mm_per_px, object, sensor, protocol, capture_hz, status, phases and
                    pose_convention (required: which way x, y, z and theta point, and the origin;
                    dataset/pose_convention.py); sensor and mm_per_px may come from options instead

Poses: +x right, +y up in the frame, z negative into the gel, theta counter-clockwise seen by
the camera, in mm and deg from the contact point (dataset/pose_convention.py).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_file import RunFileError, RunHeader, RunWriter
from acquisition.run_layout import decode_phases, phase_names
from common.table import finite_number
from dataset.import_checks import (  # noqa: F401 (MM_PER_PX: the CLI's --mm-per-px range)
    MM_PER_PX,
    STREAM_COLS,
    STREAM_CSV,
    csv_fields,
    read_meta,
    read_rows,
    read_stream,
    read_table,
    sensor_kind,
)
from dataset.import_images import Squaring, check_square, read_image, square, squared_mm_per_px
from dataset.merge import merge_runs  # noqa: F401 (merge and preview, long exported from here)
from dataset.pose_convention import POSE_CONVENTION, flipped_axes, pose_signs
from dataset.preview import preview  # noqa: F401
from dataset.runs import open_run, read
from protocols.plan import PHASES


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
            "pose_convention": POSE_CONVENTION,  # what every run file holds (dataset/pose_convention.py)
        }
    (out / "run.json").write_text(json.dumps(meta, indent=2) + "\n")
    return n


def _refuse_existing(out: Path) -> None:
    """Import writes a new run file; it never appends (a run file is only resumed by the rig)."""
    if out.exists():
        raise RunFileError(
            f"{out}: exists; dataset import writes a new run file: choose another --out, "
            f"or delete {out.name} first to import it again"
        )


def import_run(
    folder: str | Path,
    out: str | Path,
    *,
    mm_per_px: float | None = None,
    object_name: str | None = None,
    sensor: str | None = None,
    sensor_profile: str = "",
    squaring: Squaring = Squaring(),
) -> int:
    """A run file from a folder in the export format; the frame count.

    Every number, phase, file name, the pose convention, the sensor kind and the images'
    shapes are checked before the run file is created (a refused import writes nothing);
    ConfigError or RunFileError name the file, the row or key, and the value. Poses are
    converted to the run file's convention; non-square images are cropped or padded (and
    resized) only as ``squaring`` says (dataset/import_images.py). ``sensor_profile`` is the
    profile's record (``SensorProfile.record()``), stored as a collected run stores its own.
    """
    folder, out = Path(folder), Path(out)
    _refuse_existing(out)
    table, rows = read_table(folder)
    meta = read_meta(folder)
    if mm_per_px is not None:
        scale = finite_number(str(folder), "--mm-per-px", mm_per_px, low=MM_PER_PX[0], high=MM_PER_PX[1])
    elif meta.get("mm_per_px") is not None:
        scale = meta["mm_per_px"]
    else:
        raise RunFileError(f"{folder}: mm per pixel unknown: pass --mm-per-px or put mm_per_px in run.json")
    kind = sensor_kind(folder, meta, sensor)
    signs = pose_signs(str(folder / "run.json"), meta.get("pose_convention"))
    capture_hz = float(meta.get("capture_hz", 1.0))
    # A folder from another rig names phases in the standard vocabulary; an exported run
    # brings its own list, in its own order.
    phases = tuple(meta.get("phases") or PHASES)
    checked = read_rows(folder, table, rows, capture_hz, phases, signs)
    stream = read_stream(folder)
    first_raw = read_image(checked[0][0], "the first frame")
    check_square(checked[0][0], first_raw, "the first frame", squaring)
    if not (folder / "object.png").exists():
        raise RunFileError(f"{folder}: no object.png (the object's contact face is the model's condition)")
    obj_raw = read_image(folder / "object.png", "the object image")
    check_square(folder / "object.png", obj_raw, "the object image", squaring)
    reference_raw = first_raw
    if (folder / "reference.png").exists():
        reference_raw = read_image(folder / "reference.png", "the reference frame")
        check_square(folder / "reference.png", reference_raw, "the reference frame", squaring)
    first = square(first_raw, squaring)
    side = first.shape[0]
    obj = square(obj_raw, Squaring(squaring.shape))  # then brought to the frames' side, as training does
    obj = cv2.resize(obj, (side, side), interpolation=cv2.INTER_AREA if obj.shape[0] > side else cv2.INTER_LINEAR)
    reference = square(reference_raw, squaring)
    if reference.shape != first.shape:
        reference = cv2.resize(reference, (side, side), interpolation=cv2.INTER_AREA)
    flips = flipped_axes(signs)
    header = RunHeader(
        protocol_name=meta.get("protocol", "imported"),
        protocol_toml="",
        rig_config=(
            f"imported from {folder}\n"
            f"pose_convention: {json.dumps(meta['pose_convention'])}"
            f"{'; converted: ' + ', '.join(flips) + ' flipped' if flips else ''}\n"
            f"images: {first_raw.shape[1]}x{first_raw.shape[0]} -> {side}x{side} ({squaring.options()})"
        ),
        object_name=object_name or meta.get("object", "imported"),
        object_geometry="imported",
        sensor_kind=kind,
        mm_per_px=squared_mm_per_px(float(scale), first_raw.shape, squaring),
        capture_hz=capture_hz,
        frames_planned=len(rows),
        contact_origin=(0.0, 0.0, 0.0, 0.0),
        phases=phases,
        sensor_profile=sensor_profile,
    )
    writer = RunWriter.create(out, header, first.shape, obj, reference)
    try:
        for i, (frame_path, values) in enumerate(checked):
            img = first_raw if i == 0 else read_image(frame_path, f"frame {i}")
            if img.shape != first_raw.shape:
                raise RunFileError(
                    f"{frame_path}: {img.shape[1]}x{img.shape[0]} differs from the first frame's "
                    f"{first_raw.shape[1]}x{first_raw.shape[0]}"
                )
            writer.append(first if i == 0 else square(img, squaring), stream=stream if i == 0 else None, **values)
        writer.set_status("complete", "")
    except BaseException:
        writer.set_status("aborted", "import failed")
        raise
    finally:
        writer.close()
    return len(rows)
