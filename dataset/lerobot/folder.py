"""A LeRobotDataset v3.0 folder read back and checked before anything of it is used.

Refused in one line naming the file (nothing is imported): info.json missing, not JSON, another format
version, or disagreeing with the files (episode, frame or task counts; a feature the data lacks); an
episodes table, data file or video missing, unreadable or short of its episode's rows or frames; rows
whose indices are not the episodes'. A folder exported here also carries the SHA-256 of every file
(meta/tactile/export.json): a changed or missing file is named, and lossless frames must decode to the
digests recorded at export.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acquisition.writer_lock import RunFileError
from dataset.lerobot import layout as L
from dataset.lerobot.export import sha256
from dataset.lerobot.parquet import read_table
from dataset.lerobot.video import VideoError, read_video

EPISODE_COLUMNS = (
    "episode_index",
    "length",
    "data/chunk_index",
    "data/file_index",
    "dataset_from_index",
    "dataset_to_index",
)


@dataclass
class Folder:
    path: Path
    info: dict
    episodes: dict[str, np.ndarray]  # the episodes table's columns
    export: dict | None  # meta/tactile/export.json when exported here

    @property
    def record(self) -> dict:
        """export.json (a folder exported here)."""
        if self.export is None:
            raise RunFileError(f"{self.path}: not exported by this tool (no {L.EXPORT_JSON})")
        return self.export

    @property
    def fps(self) -> int:
        return int(self.info["fps"])

    def cameras(self) -> list[str]:
        return [k for k, f in self.info["features"].items() if f.get("dtype") in ("video", "image")]

    def data(self, e: int) -> dict[str, np.ndarray]:
        """Episode ``e``'s rows, in frame order."""
        return _episode_rows(self, e)

    def frames(self, e: int, camera: str):
        """Episode ``e``'s frames (BGR) from its video."""
        return _episode_frames(self, e, camera)


def _fail(path: Path, problem: str) -> RunFileError:
    return RunFileError(f"{path}: {problem}; nothing was imported")


def _json(path: Path) -> dict:
    if not path.is_file():
        raise _fail(path, "missing: not a LeRobot dataset folder (format v3.0)")
    try:
        value = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _fail(path, f"cannot be read as JSON ({exc})") from None
    if not isinstance(value, dict):
        raise _fail(path, "expected a JSON object")
    return value


def _table(path: Path) -> dict[str, np.ndarray]:
    if not path.is_file():
        raise _fail(path, "missing")
    try:
        return read_table(path)
    except Exception as exc:  # pyarrow raises many kinds for a damaged file; each is named, never a traceback
        raise _fail(path, f"cannot be read as parquet ({type(exc).__name__}: {str(exc)[:120]})") from None


def _whole(info: dict, key: str, where: Path, low: int = 0) -> int:
    value = info.get(key)
    if not isinstance(value, int) or isinstance(value, bool) or value < low:
        raise _fail(where, f"{key} is {value!r}; expected a whole number >= {low}")
    return value


def open_folder(path: Path) -> Folder:
    path = Path(path)
    if not path.is_dir():
        raise RunFileError(f"{path}: not a folder; import --format lerobot takes a LeRobot dataset folder")
    export = _json(path / L.EXPORT_JSON) if (path / L.EXPORT_JSON).exists() else None
    if export is not None:
        _check_digests(path, export)
    info_path = path / L.INFO
    info = _json(info_path)
    if info.get("codebase_version") != L.CODEBASE_VERSION:
        raise _fail(
            info_path,
            f"codebase_version {info.get('codebase_version')!r}: import reads {L.CODEBASE_VERSION} "
            "(convert an older dataset with lerobot's converter first)",
        )
    fps = info.get("fps")
    if (
        not isinstance(fps, (int, float))
        or isinstance(fps, bool)
        or not np.isfinite(fps)
        or fps <= 0
        or fps != int(fps)
    ):
        raise _fail(info_path, f"fps is {fps!r}; expected a whole number of frames per second")
    if not isinstance(info.get("features"), dict) or not info["features"]:
        raise _fail(info_path, "features: expected an object naming each feature")
    n_episodes = _whole(info, "total_episodes", info_path, 1)
    n_frames = _whole(info, "total_frames", info_path, 1)
    tables = sorted((path / "meta" / "episodes").glob("chunk-*/file-*.parquet"))
    if not tables:
        raise _fail(path / L.EPISODES, "missing: the episodes table")
    parts = [_table(t) for t in tables]
    episodes = {}
    for column in EPISODE_COLUMNS:
        if any(column not in p for p in parts):
            raise _fail(tables[0], f"no column {column!r} in the episodes table")
        episodes[column] = np.concatenate([p[column] for p in parts])
    order = np.argsort(episodes["episode_index"], kind="stable")
    episodes = {k: v[order] for k, v in episodes.items()}
    if len(order) != n_episodes or not np.array_equal(episodes["episode_index"], np.arange(n_episodes)):
        raise _fail(
            info_path,
            f"total_episodes is {n_episodes}, the episodes table lists {len(order)} "
            f"(indices {episodes['episode_index'][:5].tolist()}…)",
        )
    if int(episodes["length"].sum()) != n_frames:
        raise _fail(
            info_path, f"total_frames is {n_frames}, the episodes' lengths add up to {int(episodes['length'].sum())}"
        )
    for video in [k for k, f in info["features"].items() if f.get("dtype") == "video"]:
        for column in (
            f"videos/{video}/chunk_index",
            f"videos/{video}/file_index",
            f"videos/{video}/from_timestamp",
            f"videos/{video}/to_timestamp",
        ):
            if any(column not in p for p in parts):
                raise _fail(tables[0], f"no column {column!r} in the episodes table (video {video})")
            episodes[column] = np.concatenate([p[column] for p in parts])[order]
    return Folder(path, info, episodes, export)


def _check_digests(path: Path, export: dict) -> None:
    if export.get("format") != L.FORMAT_MARK or not isinstance(export.get("files"), dict):
        raise _fail(path / L.EXPORT_JSON, f"format {export.get('format')!r}: expected {L.FORMAT_MARK!r}")
    for name, digest in export["files"].items():
        file = path / name
        if not file.is_file():
            raise _fail(file, "missing (listed in meta/tactile/export.json)")
        if sha256(file) != digest:
            raise _fail(file, "changed since export (its SHA-256 differs from meta/tactile/export.json's)")


def _episode_rows(folder: Folder, e: int) -> dict[str, np.ndarray]:
    ep = {k: int(v[e]) for k, v in folder.episodes.items() if not k.endswith("timestamp")}
    file = folder.path / folder.info.get("data_path", L.DATA_PATH).format(
        chunk_index=ep["data/chunk_index"], file_index=ep["data/file_index"]
    )
    table = _table(file)
    if "episode_index" not in table or "index" not in table:
        raise _fail(file, "no episode_index or index column")
    mine = table["episode_index"] == e
    rows = {k: v[mine] for k, v in table.items()}
    if len(rows["index"]) != ep["length"]:
        raise _fail(file, f"episode {e} has {len(rows['index'])} rows; the episodes table says {ep['length']}")
    expected = np.arange(ep["dataset_from_index"], ep["dataset_to_index"])
    if not np.array_equal(np.sort(rows["index"]), expected):
        raise _fail(file, f"episode {e}'s rows are not indices {expected[0]}…{expected[-1]} as the episodes table says")
    order = np.argsort(rows["frame_index"] if "frame_index" in rows else rows["index"], kind="stable")
    missing = [k for k, f in folder.info["features"].items() if f.get("dtype") not in ("video",) and k not in rows]
    if missing:
        raise _fail(file, f"no column {missing[0]!r}, which info.json's features list")
    return {k: v[order] for k, v in rows.items()}


def _episode_frames(folder: Folder, e: int, camera: str):
    fps = folder.fps
    chunk = int(folder.episodes[f"videos/{camera}/chunk_index"][e])
    index = int(folder.episodes[f"videos/{camera}/file_index"][e])
    file = folder.path / folder.info.get("video_path", L.VIDEO_PATH).format(
        video_key=camera, chunk_index=chunk, file_index=index
    )
    if not file.is_file():
        raise _fail(file, f"missing: the video of episode {e}")
    first = int(round(float(folder.episodes[f"videos/{camera}/from_timestamp"][e]) * fps))
    length = int(folder.episodes["length"][e])
    n = 0
    try:
        for k, frame in enumerate(read_video(file)):
            if k < first:
                continue
            if n == length:
                break
            n += 1
            yield frame
    except VideoError as exc:
        raise _fail(file, str(exc).removeprefix(f"{file}: ")) from None
    if n != length:
        raise _fail(file, f"{n} frames of episode {e} decode; the episodes table says {length} (a truncated video?)")
