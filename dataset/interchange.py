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
    run.json        mm_per_px, object, object_geometry, sensor, protocol, capture_hz, status and reason,
                    frames_planned, sensor_profile (the recorded profile's text, "": none), phases
                    and pose_convention (required: which way x, y, z and theta point, and the
                    origin; dataset/pose_convention.py); sensor and mm_per_px may come from options
                    instead (dataset/import_meta.py checks each key)

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
from acquisition.run_reader import RunReader
from acquisition.run_writer import RunHeader
from acquisition.whole_run import check_new_output, whole_folder, whole_run
from acquisition.writer_lock import RunFileError
from common.table import finite_number
from dataset.import_checks import (
    STREAM_COLS,
    STREAM_CSV,
    absent_columns,
    csv_fields,
    read_rows,
    read_stream,
    read_table,
    row_order,
)
from dataset.import_images import Squaring, check_square, read_image, square, squared_mm_per_px
from dataset.import_meta import (  # noqa: F401 (MM_PER_PX: the CLI's --mm-per-px range)
    MM_PER_PX,
    imported_profile,
    imported_status,
    planned_frames,
    read_meta,
    sensor_kind,
)
from dataset.merge import merge_runs  # noqa: F401 (merge and preview, long exported from here)
from dataset.pose_convention import POSE_CONVENTION, flipped_axes, pose_signs
from dataset.preview import preview  # noqa: F401
from protocols.plan import PHASES


def _cell(value, field: S.Field) -> str:
    return str(int(value)) if np.dtype(field.dtype).kind in "iu" else repr(float(value))


def export_run(path: str | Path, out: str | Path) -> int:
    """frames/*.png, frames.csv (every per-frame field of the table the file has), object.png,
    reference.png, wrench_stream.csv (when recorded) and run.json in a new folder ``out``; the frame
    count. The run is read through the verified reader (acquisition/run_reader.py: rows, attributes
    and images at open, each frame's checksum as it is read) and the folder written under a
    temporary name beside ``out``, renamed only when complete: a refused export leaves nothing."""
    out = Path(out)
    if out.exists() and not (out.is_dir() and not any(out.iterdir())):
        raise RunFileError(f"--out {out}: exists; export writes a new folder: choose another --out")
    if not out.parent.is_dir():
        raise RunFileError(f"--out {out}: the folder {out.parent} does not exist; create it first")
    with RunReader.open(path) as run, whole_folder(out, "export") as tmp:
        _export(run, tmp)
        return run.n


def _png(path: Path, image: np.ndarray) -> None:
    if not cv2.imwrite(str(path), image):
        raise OSError(f"cannot write {path}")


def _export(run: RunReader, folder: Path) -> None:
    (folder / "frames").mkdir(parents=True)
    n = run.n
    fields = [fl for fl in csv_fields() if fl.path in run.f]
    values = {fl.path: run.rows[fl.path] for fl in fields}
    if S.PHASE_INDEX in values:  # by name, through the file's own phases
        values[S.PHASE_INDEX] = np.array([run.phases[int(k)] for k in values[S.PHASE_INDEX]], dtype=object)
    with open(folder / "frames.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["file", *(c for fl in fields for c in S.columns_of(fl))])
        for i in range(n):
            name = f"frames/{i:06d}.png"
            _png(folder / name, run.frame(i))
            cells = [name]
            for fl in fields:
                v = values[fl.path][i]
                cells += [v] if fl.path == S.PHASE_INDEX else [_cell(x, fl) for x in np.atleast_1d(v)]
            w.writerow(cells)
    if run.stream is not None and len(run.stream):
        with open(folder / STREAM_CSV, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(STREAM_COLS)
            w.writerows([repr(float(x)) for x in r] for r in run.stream)
    _png(folder / "object.png", run.image(S.OBJECT_IMAGE))
    _png(folder / "reference.png", run.image(S.REFERENCE_FRAME))
    scale = run.number(S.ATTR_MM_PER_PX)
    meta = {
        "mm_per_px": scale if np.isfinite(scale) else None,  # null: uncalibrated (JSON has no NaN)
        "object": run.text(S.ATTR_OBJECT),
        "object_geometry": run.text(S.ATTR_OBJECT_GEOMETRY),
        "sensor": run.text(S.ATTR_SENSOR_KIND),
        "protocol": run.text(S.ATTR_PROTOCOL_NAME),
        "capture_hz": run.number(S.ATTR_CAPTURE_HZ),
        "status": run.status,
        "reason": run.reason,
        "frames_planned": int(run.number(S.ATTR_FRAMES_PLANNED)),
        "sensor_profile": run.text(S.ATTR_SENSOR_PROFILE),  # the profile's record ("": the run has none)
        "phases": list(run.phases),
        "pose_convention": POSE_CONVENTION,  # what every run file holds (dataset/pose_convention.py)
    }
    (folder / "run.json").write_text(json.dumps(meta, indent=2) + "\n")


def import_run(
    folder: str | Path,
    out: str | Path,
    *,
    mm_per_px: float | None = None,
    object_name: str | None = None,
    sensor: str | None = None,
    sensor_profile: str = "",
    squaring: Squaring = Squaring(),
    ignore_columns: tuple[str, ...] = (),
    say=lambda line: None,
) -> int:
    """A run file from a folder in the export format; the frame count.

    Every number, phase, file name, the pose convention, the sensor kind and the images'
    shapes are checked before the run file is created (a refused import writes nothing);
    ConfigError or RunFileError name the file, the row or key, and the value. Poses are
    converted to the run file's convention; non-square images are cropped or padded (and
    resized) only as ``squaring`` says (dataset/import_images.py). ``sensor_profile`` is the
    profile's record (``SensorProfile.record()``), stored as a collected run stores its own ("":
    the run says it has none). ``ignore_columns``: frames.csv columns to leave out (any other
    column the format does not know is refused). ``say`` hears which absent columns took their
    documented default. The file appears at ``out`` only once complete (acquisition/whole_run.py).
    """
    folder, out = Path(folder), Path(out)
    check_new_output(out, "dataset import")
    table, columns, rows = read_table(folder, tuple(ignore_columns))
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
    row_order(table, checked, phases)  # what every reader of the run file checks: refused now, not after
    status, reason = imported_status(folder, meta)
    planned = planned_frames(folder, meta, len(rows))
    profile = imported_profile(folder, meta, sensor_profile)
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
    filled = absent_columns(columns)
    if filled:
        say(f"frames.csv has no column for: {'; '.join(filled)} (the format's defaults)")
    header = RunHeader(
        protocol_name=meta.get("protocol", "imported"),
        protocol_toml="",
        rig_config=(
            f"imported from {folder}\n"
            f"pose_convention: {json.dumps(meta['pose_convention'])}"
            f"{'; converted: ' + ', '.join(flips) + ' flipped' if flips else ''}\n"
            f"images: {first_raw.shape[1]}x{first_raw.shape[0]} -> {side}x{side} ({squaring.options()})"
            + (f"\ncolumns absent, defaults taken: {'; '.join(filled)}" if filled else "")
            + (f"\ncolumns ignored: {', '.join(ignore_columns)}" if ignore_columns else "")
        ),
        object_name=object_name or meta.get("object", "imported"),
        object_geometry=meta.get("object_geometry", "imported")
        if object_name in (None, meta.get("object"))
        else "imported",
        sensor_kind=kind,
        mm_per_px=squared_mm_per_px(float(scale), first_raw.shape, squaring),
        capture_hz=capture_hz,
        frames_planned=planned,
        contact_origin=(0.0, 0.0, 0.0, 0.0),
        phases=phases,
        sensor_profile=profile,
    )
    with whole_run(out, header, first.shape, obj, reference, what="dataset import") as writer:
        for i, (frame_path, values) in enumerate(checked):
            img = first_raw if i == 0 else read_image(frame_path, f"frame {i}")
            if img.shape != first_raw.shape:
                raise RunFileError(
                    f"{frame_path}: {img.shape[1]}x{img.shape[0]} differs from the first frame's "
                    f"{first_raw.shape[1]}x{first_raw.shape[0]}"
                )
            writer.append(first if i == 0 else square(img, squaring), stream=stream if i == 0 else None, **values)
        writer.set_status(status, reason)
    return len(rows)
