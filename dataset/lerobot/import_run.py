"""A LeRobot folder back into run files.

A folder exported here (meta/tactile/export.json) comes back run by run: its episodes regathered in the
run's frame order, the run's record (protocol, rig, object, sensor profile, status, phases, origin), its
object image, reference frame and full-rate wrench stream as they were; with the lossless codec every
frame is the run's, checked against the digests recorded at export.

A folder from elsewhere: each episode becomes a run. Its camera (``camera``, or its only video/image
feature), the wrench (six values) and the pose (four: x, y, z in mm, θ in degrees) are required by the
model and refused in one line naming the key when absent; the object image, mm per pixel and the sensor
kind come from the options (dataset/lerobot/foreign.py).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_writer import RunHeader
from acquisition.whole_run import whole_run
from acquisition.writer_lock import RunFileError
from dataset.lerobot import layout as L
from dataset.lerobot.export import frame_digest
from dataset.lerobot.folder import Folder, open_folder
from dataset.lerobot.foreign import import_foreign
from dataset.lerobot.outputs import outputs


def import_lerobot(path: Path, out: Path, *, say=lambda line: None, **foreign) -> list[tuple[Path, int]]:
    """Run files from a LeRobot folder (module docstring); (file, frames) of each written."""
    folder = open_folder(Path(path))
    if folder.export is None:
        return import_foreign(folder, Path(out), say=say, **foreign)
    runs = folder.record["runs"]
    names = [Path(r["file"]).stem + ".h5" for r in runs]
    plans = [_gather(folder, r) for r in range(len(runs))]  # every row read and checked before any file
    written = []
    with outputs(Path(out), names) as targets:
        for r, (target, rows) in enumerate(zip(targets, plans)):
            _write_run(folder, r, target, rows)
            written.append((Path(out) / names[r] if len(targets) > 1 else target, len(rows[L.FRAME_IN_RUN])))
    for (target, n), run in zip(written, runs):
        say(f"{target}: {n} frames of {run['file']}")
    return written


def _gather(folder: Folder, r: int) -> dict[str, np.ndarray]:
    """Run ``r``'s rows from all its episodes, in the run's frame order, with each row's (episode, k)."""
    mine = [e for e, ep in enumerate(folder.record["episodes"]) if ep["run"] == r]
    tables = [folder.data(e) for e in mine]
    rows = {k: np.concatenate([t[k] for t in tables]) for k in tables[0]}
    rows["_episode"] = np.concatenate([np.full(len(t["index"]), e) for e, t in zip(mine, tables)])
    rows["_k"] = np.concatenate([np.arange(len(t["index"])) for t in tables])
    order = np.argsort(rows[L.FRAME_IN_RUN], kind="stable")
    rows = {k: v[order] for k, v in rows.items()}
    n = folder.record["runs"][r]["frames"]
    if not np.array_equal(rows[L.FRAME_IN_RUN], np.arange(n)):
        raise RunFileError(
            f"{folder.path}: the episodes of run {folder.record['runs'][r]['file']} hold "
            f"{len(rows[L.FRAME_IN_RUN])} frames, not each of its {n} once; nothing was imported"
        )
    return rows


def _image(path: Path) -> np.ndarray:
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise RunFileError(f"{path}: missing or not an image; nothing was imported")
    return image


def header_of(record: dict) -> RunHeader:
    return RunHeader(
        protocol_name=record["protocol"],
        protocol_toml=record["protocol_toml"],
        rig_config=record["rig_config"],
        object_name=record["object"],
        object_geometry=record["object_geometry"],
        sensor_kind=record["sensor"],
        mm_per_px=float("nan") if record["mm_per_px"] is None else float(record["mm_per_px"]),
        capture_hz=float(record["capture_hz"]),
        frames_planned=int(record["frames_planned"]),
        contact_origin=tuple(float(v) for v in record["contact_origin"]),  # type: ignore[arg-type]
        phases=tuple(record["phases"]),
        sensor_profile=record["sensor_profile"],
        object_file_toml=record["object_file_toml"],
        object_photo_sha256=record["object_photo_sha256"],
    )


def _frames(folder: Folder, rows: dict[str, np.ndarray]):
    """The run's frames in its order; checked against export's digests when lossless. Each episode's video
    is decoded once, in order (a split's parts interleave in the run: one decoder per episode)."""
    decoders: dict[int, Iterator[np.ndarray]] = {}
    for e, k in zip(rows["_episode"].tolist(), rows["_k"].tolist()):
        if e not in decoders:
            decoders[e] = iter(folder.frames(e, L.CAMERA))
        frame = next(decoders[e])  # rows of one episode come in its frame order: k = 0, 1, ...
        if folder.record["lossless"] and frame_digest(frame) != folder.record["episodes"][e]["frame_blake2b"][k]:
            raise RunFileError(
                f"{folder.path / L.video_file(e)}: frame {k} differs from the one exported; nothing was imported"
            )
        yield frame


def _write_run(folder: Folder, r: int, target: Path, rows: dict[str, np.ndarray]) -> None:
    where = folder.path / L.run_folder(r)
    record = json.loads((where / "run.json").read_text())
    stream_file = where / "wrench_stream.npy"
    stream = np.load(stream_file, allow_pickle=False) if stream_file.exists() else None
    obj, reference = _image(where / "object.png"), _image(where / "reference.png")
    shape = tuple(folder.info["features"][L.CAMERA]["shape"])
    with whole_run(target, header_of(record), shape, obj, reference, what="dataset import") as writer:
        for i, frame in enumerate(_frames(folder, rows)):
            values = {fl.path: _value(rows[L.feature_name(fl)][i], fl) for fl in S.PER_FRAME_FIELDS}
            writer.append(frame, stream=stream if i == 0 else None, **values)
        writer.set_status(record["status"], record["reason"])
        if record["sim_solver_warnings"] >= 0:
            writer.set_sim_solver_warnings(int(record["sim_solver_warnings"]))


def _value(v, fl: S.Field):
    v = np.asarray(v, dtype=fl.dtype)
    return v if fl.shape else v.reshape(-1)[0]
