"""The metadata files of an exported folder: info.json, the episodes and tasks tables, each run's record
and the dataset card (README.md) whose metadata block the Hub's viewer reads."""

from __future__ import annotations

import numpy as np

from acquisition import schema as S
from dataset.lerobot import layout as L
from dataset.pose_convention import POSE_CONVENTION

ROBOT_TYPE = "tactile_rig"  # x, y, z and rotary stages pressing objects on a vision-based tactile sensor


def run_record(run) -> dict:
    """Everything a run file says about itself, JSON (NaN mm per pixel: null), for import to write back."""
    scale = run.number(S.ATTR_MM_PER_PX)
    warnings = int(run.f[S.SIM_SOLVER_WARNINGS][()]) if S.SIM_SOLVER_WARNINGS in run.f else -1
    return {
        "protocol": run.text(S.ATTR_PROTOCOL_NAME),
        "protocol_toml": run.text(S.ATTR_PROTOCOL),
        "rig_config": run.text(S.ATTR_RIG_CONFIG),
        "object": run.text(S.ATTR_OBJECT),
        "object_geometry": run.text(S.ATTR_OBJECT_GEOMETRY),
        "object_file_toml": run.text(S.ATTR_OBJECT_FILE),
        "object_photo_sha256": run.text(S.ATTR_OBJECT_PHOTO_SHA256),
        "sensor": run.text(S.ATTR_SENSOR_KIND),
        "sensor_profile": run.text(S.ATTR_SENSOR_PROFILE),  # as stored (the property strips it)
        "mm_per_px": scale if np.isfinite(scale) else None,
        "capture_hz": run.number(S.ATTR_CAPTURE_HZ),
        "frames_planned": int(run.number(S.ATTR_FRAMES_PLANNED)),
        "contact_origin": [float(v) for v in np.asarray(run.attrs[S.ATTR_CONTACT_ORIGIN]).reshape(-1)],
        "phases": list(run.phases),
        "status": run.status,
        "reason": run.reason,
        "sim_solver_warnings": warnings,
        "created_utc": run.text(S.ATTR_CREATED),
        "software_version": run.text(S.ATTR_SOFTWARE),
        "frames": run.n,
        "pose_convention": POSE_CONVENTION,
    }


def info_json(features: dict, fps: int, episodes: int, frames: int, tasks: int, splits: dict) -> dict:
    return {
        "codebase_version": L.CODEBASE_VERSION,
        "robot_type": ROBOT_TYPE,
        "total_episodes": episodes,
        "total_frames": frames,
        "total_tasks": tasks,
        "chunks_size": L.CHUNKS_SIZE,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 200,
        "fps": fps,
        "splits": splits,
        "data_path": L.DATA_PATH,
        "video_path": L.VIDEO_PATH,
        "features": features,
    }


def _column(dtype: str) -> dict:
    return {"dtype": dtype, "shape": [1], "names": None}


def episodes_table(rows: list[dict], fps: int) -> tuple[dict, dict]:
    """(columns, features) of meta/episodes: per episode its tasks, length, rows and video span."""
    video = f"videos/{L.CAMERA}"
    n = len(rows)
    columns: dict = {
        "episode_index": np.arange(n, dtype=np.int64),
        "tasks": [[r["task"]] for r in rows],
        "length": np.array([r["length"] for r in rows], dtype=np.int64),
        "data/chunk_index": np.arange(n, dtype=np.int64) // L.CHUNKS_SIZE,
        "data/file_index": np.arange(n, dtype=np.int64) % L.CHUNKS_SIZE,
        "dataset_from_index": np.array([r["from"] for r in rows], dtype=np.int64),
        "dataset_to_index": np.array([r["from"] + r["length"] for r in rows], dtype=np.int64),
        f"{video}/chunk_index": np.arange(n, dtype=np.int64) // L.CHUNKS_SIZE,
        f"{video}/file_index": np.arange(n, dtype=np.int64) % L.CHUNKS_SIZE,
        f"{video}/from_timestamp": np.zeros(n),
        f"{video}/to_timestamp": np.array([r["length"] / fps for r in rows]),
        "meta/episodes/chunk_index": np.zeros(n, dtype=np.int64),
        "meta/episodes/file_index": np.zeros(n, dtype=np.int64),
    }
    features = {k: _column("float64" if k.endswith("timestamp") else "int64") for k in columns}
    features["tasks"] = {"dtype": "string_list", "shape": [1], "names": None}
    return columns, features


def tasks_table(tasks: list[str]) -> tuple[dict, dict, str]:
    """(columns, features, index) of meta/tasks.parquet: the task strings as the pandas index."""
    columns = {"task_index": np.arange(len(tasks), dtype=np.int64), "task": list(tasks)}
    return columns, {"task_index": _column("int64"), "task": _column("string")}, "task"
