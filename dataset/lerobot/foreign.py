"""A LeRobot folder made elsewhere into run files: one per episode, with the fields it has.

The model cannot go without the tactile camera, the wrench at each frame, the pose that places the object
image and that image itself; each is refused in one line naming the key or option when absent. What a
run file records but the folder does not say (the commanded pose, phases, the stream) takes the run
file's documented fill, and the import says which.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_writer import RunHeader
from acquisition.whole_run import whole_run
from acquisition.writer_lock import RunFileError
from common.sensors import SENSOR_KINDS
from common.table import finite_number
from dataset.lerobot import layout as L
from dataset.lerobot.folder import Folder
from dataset.lerobot.outputs import outputs
from protocols.plan import PHASES

WRENCH_KEY = "observation.wrench"
POSE_KEY = "observation.state"


def _camera(folder: Folder, camera: str | None) -> str:
    info = folder.path / L.INFO
    cameras = folder.cameras()
    if camera is not None:
        if camera not in cameras:
            raise RunFileError(f"{info}: --camera {camera!r} is not a camera feature (cameras: {', '.join(cameras)})")
        return camera
    tactile = [c for c in cameras if "tactile" in c or "gelsight" in c.lower() or "digit" in c.lower()]
    if len(cameras) == 1:
        return cameras[0]
    if len(tactile) == 1:
        return tactile[0]
    if not cameras:
        raise RunFileError(f"{info}: no camera feature (dtype video): the model learns the tactile camera's frames")
    raise RunFileError(f"{info}: cameras {', '.join(cameras)}: name the tactile one with --camera")


def _feature(folder: Folder, key: str, width: int, option: str, what: str) -> str:
    feature = folder.info["features"].get(key)
    if feature is None or list(feature.get("shape", [])) != [width]:
        found = "absent" if feature is None else f"shape {feature.get('shape')}"
        raise RunFileError(
            f"{folder.path / L.INFO}: feature {key!r} ({found}): the model needs {what}; "
            f"name a feature of {width} values with {option}"
        )
    return key


def import_foreign(
    folder: Folder,
    out: Path,
    *,
    camera=None,
    wrench_key=None,
    pose_key=None,
    object_image=None,
    mm_per_px=None,
    sensor=None,
    object_name=None,
    say=lambda line: None,
) -> list[tuple[Path, int]]:
    cam = _camera(folder, camera)
    if folder.info["features"][cam].get("dtype") != "video":
        raise RunFileError(f"{folder.path / L.INFO}: camera {cam!r} is stored as images; import reads video cameras")
    wrench = _feature(
        folder,
        wrench_key or WRENCH_KEY,
        6,
        "--wrench-key",
        "the wrench (Fx, Fy, Fz in N, Mx, My, Mz in N·mm), its force condition",
    )
    pose = _feature(
        folder,
        pose_key or POSE_KEY,
        4,
        "--pose-key",
        "the pose (x, y, z in mm, θ in degrees) that places the object image",
    )
    if object_image is None:
        raise RunFileError(
            f"{folder.path}: no object image: the object's contact face is the model's condition; "
            "pass --object-image PNG"
        )
    obj = cv2.imread(str(object_image), cv2.IMREAD_COLOR)
    if obj is None:
        raise RunFileError(f"--object-image {object_image}: missing or not an image")
    if mm_per_px is None:
        raise RunFileError(f"{folder.path}: mm per pixel unknown: pass --mm-per-px")
    scale = finite_number(str(folder.path), "--mm-per-px", mm_per_px, low=1e-4, high=10.0)
    if sensor not in SENSOR_KINDS:
        raise RunFileError(f"{folder.path}: sensor kind unknown: pass --sensor ({', '.join(SENSOR_KINDS)})")
    h, w, _ = folder.info["features"][cam]["shape"]
    if h != w:
        raise RunFileError(f"{folder.path / L.INFO}: camera {cam!r} is {w}x{h} px; run files hold square frames")
    obj = cv2.resize(obj, (w, h), interpolation=cv2.INTER_AREA)
    n = len(folder.episodes["length"])
    names = [f"episode_{e:06d}.h5" for e in range(n)]
    tables = [folder.data(e) for e in range(n)]  # every row read and checked before any file
    written = []
    with outputs(out, names) as targets:
        for e, (target, rows) in enumerate(zip(targets, tables)):
            _write(folder, e, target, rows, cam, wrench, pose, obj, scale, sensor, object_name or "imported")
            written.append((out / names[e] if len(targets) > 1 else target, len(rows["index"])))
    say(
        f"{folder.path}: absent, the run file's fill taken: commanded pose (the measured one), phase (press), "
        "level, step, wrench skew, full-rate stream"
    )
    for e, (target, k) in enumerate(written):
        say(f"{target}: {k} frames of episode {e}")
    return written


def _write(folder, e, target, rows, cam, wrench, pose, obj, scale, sensor, object_name) -> None:
    frames = folder.frames(e, cam)
    first = next(frames)
    header = RunHeader(
        protocol_name="lerobot",
        protocol_toml="",
        rig_config=f"imported from the LeRobot folder {folder.path}, episode {e} (camera {cam}, wrench {wrench}, "
        f"pose {pose})",
        object_name=object_name,
        object_geometry="imported",
        sensor_kind=sensor,
        mm_per_px=scale,
        capture_hz=float(folder.fps),
        frames_planned=len(rows["index"]),
        contact_origin=(0.0, 0.0, 0.0, 0.0),
        phases=PHASES,
    )
    t = np.asarray(rows["timestamp"], dtype=np.float64)
    for key in (wrench, pose):
        if not np.all(np.isfinite(np.asarray(rows[key], dtype=np.float64))):
            raise RunFileError(f"{folder.path}: episode {e}: {key} holds NaN or infinite values; nothing was imported")
    with whole_run(target, header, first.shape, obj, first, what="dataset import") as writer:
        for i, frame in enumerate([first, *frames]):
            row = S.blank_row()
            row[S.WRENCH] = np.asarray(rows[wrench][i], dtype=np.float64)
            row[S.POSE_MEASURED] = row[S.POSE_COMMANDED] = np.asarray(rows[pose][i], dtype=np.float64)
            row[S.T_FRAME] = row[S.T_CAPTURE] = t[i]
            row[S.CAPTURE_INDEX] = np.int64(rows["frame_index"][i])
            writer.append(frame, **row)
        writer.set_status("complete")
