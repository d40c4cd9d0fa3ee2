"""Write a LeRobot dataset folder with the ecosystem's own writer, from arrays in an .npz.

    python write.py FOLDER IN.npz [--fps N] [--video] [--vcodec libsvtav1|h264|hevc]

IN.npz holds one array per feature, row i being frame i: uint8 (N, H, W, 3) arrays become camera features
("image": PNG in the parquet, or with --video "video": encoded by the writer), other (N, D) arrays vectors of
their dtype; plus "episode_index" (N,), frames of an episode together and in order, and "task" (N,) texts.
"__names__" (optional): JSON text {feature: [names]}. Uses LeRobotDataset.create, add_frame per row,
save_episode per episode and finalize, as a recording would. Run like read.py (tests/lerobot_support.py).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

SPECIAL = ("episode_index", "task", "__names__")


def write(folder: Path, arrays: dict[str, np.ndarray], fps: int, video: bool, vcodec: str) -> None:
    from ledataset.datasets.lerobot_dataset import LeRobotDataset

    names = json.loads(str(arrays["__names__"])) if "__names__" in arrays else {}
    features = {}
    for key, values in arrays.items():
        if key in SPECIAL:
            continue
        if values.dtype == np.uint8 and values.ndim == 4:
            dtype = "video" if video else "image"
            features[key] = {"dtype": dtype, "shape": values.shape[1:], "names": ["height", "width", "channels"]}
        else:
            shape = values.shape[1:] or (1,)
            features[key] = {"dtype": str(values.dtype), "shape": shape, "names": names.get(key)}
    ds = LeRobotDataset.create(
        repo_id="local/tactile", root=folder, fps=fps, features=features, use_videos=video, vcodec=vcodec
    )
    episodes = arrays["episode_index"]
    for i in range(len(episodes)):
        frame = {key: arrays[key][i] if arrays[key].ndim > 1 else arrays[key][i : i + 1] for key in features}
        ds.add_frame({**frame, "task": str(arrays["task"][i])})
        if i + 1 == len(episodes) or episodes[i + 1] != episodes[i]:
            ds.save_episode()
    ds.finalize()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("arrays", type=Path)
    parser.add_argument("--fps", type=int, default=1)
    parser.add_argument("--video", action="store_true")
    parser.add_argument("--vcodec", default="libsvtav1", choices=("libsvtav1", "h264", "hevc"))
    args = parser.parse_args(argv)
    with np.load(args.arrays, allow_pickle=False) as z:
        arrays = {key: z[key] for key in z.files}
    write(args.folder, arrays, args.fps, args.video, args.vcodec)
    return 0


if __name__ == "__main__":
    sys.exit(main())
