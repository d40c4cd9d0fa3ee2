"""Read a LeRobot dataset folder with the ecosystem's own reader and write every item to an .npz.

    python read.py FOLDER OUT.npz [--video-backend torchcodec|pyav]

Run by tests/lerobot_support.py in a process of its own: this folder first on PYTHONPATH (its torchvision is a
stub, see torchvision/__init__.py), HF_HUB_OFFLINE=1, and for torchcodec FFmpeg's shared libraries on
LD_LIBRARY_PATH. Loads LeRobotDataset(repo_id="local/tactile", root=FOLDER, video_backend=...) and writes:

- per item key (observation.state, observation.wrench, action, timestamp, frame_index, episode_index, index,
  task_index, task, each camera key, ...): the values of all items stacked, item 0 first; camera keys (video and
  image features) back to uint8 (N, H, W, C) through round(x * 255), the reader giving float (C, H, W) in [0, 1];
- meta_info: ds.meta.info as JSON text; meta_stats: ds.meta.stats as JSON text, meta_stats_keys its keys;
  meta_tasks: the tasks' texts in task_index order; meta_camera_keys, meta_video_keys;
- num_frames, num_episodes (the dataset's), episodes (the episode indices present, sorted);
- seconds_load, seconds_items: how long the loading and the reading of all items took.

Exits 2 with the reader's error (its type, text and traceback on stderr) when loading or reading fails.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if hasattr(value, "tolist"):  # numpy arrays and scalars, torch tensors
        return value.tolist()
    return value


def _stack(key: str, values: list[Any], camera: bool) -> np.ndarray:
    import torch

    if camera:
        frames = torch.stack(values)  # (N, C, H, W) float in [0, 1]
        return frames.mul(255).round().clamp(0, 255).to(torch.uint8).permute(0, 2, 3, 1).contiguous().numpy()
    if isinstance(values[0], torch.Tensor):
        return torch.stack(values).numpy()
    if isinstance(values[0], str):
        return np.array(values, dtype=str)
    return np.asarray(values)


def read(folder: Path, out: Path, video_backend: str) -> None:
    from ledataset.datasets.lerobot_dataset import LeRobotDataset

    t0 = time.perf_counter()
    ds = LeRobotDataset(repo_id="local/tactile", root=folder, video_backend=video_backend)
    t1 = time.perf_counter()
    cameras = set(ds.meta.camera_keys)
    columns: dict[str, list[Any]] = {}
    for i in range(len(ds)):
        item = ds[i]
        if i == 0:
            columns = {key: [] for key in item}
        if set(item) != set(columns):
            raise RuntimeError(f"item {i} has keys {sorted(item)}, item 0 had {sorted(columns)}")
        for key, value in item.items():
            columns[key].append(value)
    t2 = time.perf_counter()
    arrays = {key: _stack(key, values, key in cameras) for key, values in columns.items()}
    stats = ds.meta.stats or {}
    tasks = ds.meta.tasks.sort_values("task_index").index.tolist() if ds.meta.tasks is not None else []
    arrays.update(
        meta_info=np.array(json.dumps(_jsonable(ds.meta.info))),
        meta_stats=np.array(json.dumps(_jsonable(stats))),
        meta_stats_keys=np.array(sorted(stats), dtype=str),
        meta_tasks=np.array(tasks, dtype=str),
        meta_camera_keys=np.array(sorted(cameras), dtype=str),
        meta_video_keys=np.array(sorted(ds.meta.video_keys), dtype=str),
        num_frames=np.array(ds.num_frames),
        num_episodes=np.array(ds.num_episodes),
        episodes=np.array(sorted({int(e) for e in arrays.get("episode_index", np.zeros(0, int)).reshape(-1)})),
        seconds_load=np.array(t1 - t0),
        seconds_items=np.array(t2 - t1),
    )
    with open(out, "wb") as f:
        np.savez(f, **arrays)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--video-backend", default="torchcodec", choices=("torchcodec", "pyav"))
    args = parser.parse_args(argv)
    if os.environ.get("HF_HUB_OFFLINE") != "1":
        print("read.py: set HF_HUB_OFFLINE=1 (the reader must not reach the Hub)", file=sys.stderr)
        return 2
    try:
        read(args.folder, args.out, args.video_backend)
    except Exception as e:  # the reader's own error, reported as it is
        traceback.print_exc()
        print(f"LeRobotDataset could not read {args.folder}: {type(e).__name__}: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
