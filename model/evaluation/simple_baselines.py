"""Baselines that need no model: what a report's numbers must beat to mean anything.

For each test frame, at the model's size:

- **background**: the run's no-contact frame (a model that draws nothing);
- **mean training frame**: the mean of the training frames (one image for every test frame);
- **background + mean contact at the pose**: the run's no-contact frame plus the mean contact of
  the training frames in contact — each frame's difference from its no-contact frame moved and
  turned so that its pose sits at the image centre, averaged — moved and turned to the test
  frame's pose (a frame without contact gets the background alone);
- **nearest training frame by condition**: the training frame whose condition is nearest —
  the same object where the training part has it, then the least distance over the pose's x, y, θ
  and the six wrench components, each in units of its training standard deviation.

The calibrated physics render is the fifth (model/conditioning/baseline.py). Frames are read through the split's
PyTorch Dataset and run rows through the verified reader: nothing is read around verification.
"""

from __future__ import annotations

from typing import Callable

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader

BACKGROUND = "background (the run's no-contact frame)"
MEAN_FRAME = "mean training frame"
PASTED = "background + mean training contact at the pose"
NEAREST = "nearest training frame by condition"
NAMES = (BACKGROUND, MEAN_FRAME, PASTED, NEAREST)
TRAIN_FRAMES = 400  # training frames averaged for the mean frame and the mean contact (spread evenly)


def _move(image: np.ndarray, dx_px: float, dy_px: float, theta_deg: float) -> np.ndarray:
    """``image`` turned by θ (counter-clockwise as seen, the pose convention) about its centre, then
    moved by (dx, dy) px (x right, y down); uncovered pixels 0."""
    h, w = image.shape[:2]
    m = cv2.getRotationMatrix2D(((w - 1) / 2, (h - 1) / 2), theta_deg, 1.0)
    m[0, 2] += dx_px
    m[1, 2] += dy_px
    return cv2.warpAffine(image, m, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def _pose_px(pose: np.ndarray, mm_per_px: float) -> tuple[float, float, float]:
    """(dx, dy px in image axes, θ deg) of a pose (x right, y up in mm)."""
    return float(pose[0]) / mm_per_px, -float(pose[1]) / mm_per_px, float(pose[3])


def _backgrounds(paths: list[str], size: int) -> dict[int, np.ndarray]:
    out = {}
    for run, path in enumerate(paths):
        with RunReader.open(path) as f:
            ref = f.image(S.REFERENCE_FRAME)
        out[run] = ref if ref.shape[:2] == (size, size) else cv2.resize(ref, (size, size), interpolation=cv2.INTER_AREA)
    return out


def _scale(data, run: int, size: int) -> float:
    """mm per pixel of run ``run``'s frames at ``size`` px across."""
    width = int(data.manifest["runs"][run]["frame_shape"][1])
    return data.mm_per_px[run] * width / size


def simple_baselines(
    split_dir,
    items: list[dict],
    size: int,
    *,
    log: Callable[[str], None] = lambda line: None,
) -> dict[str, list[np.ndarray]]:
    """Each baseline's frame (BGR uint8, size²) for every test ``items`` (TactileDataset items of one
    part of ``split_dir``), keyed by the names above."""
    from dataset.torch_dataset import TactileDataset, spread, uint8_tensor_to_image

    train = TactileDataset(split_dir, "train", size=size)
    backgrounds = _backgrounds(train.runs, size)
    rows = {run: _rows(path) for run, path in enumerate(train.runs)}
    wrench = np.stack([rows[int(r)][0][int(f)] for r, f in train.rows])
    pose = np.stack([rows[int(r)][1][int(f)] for r, f in train.rows])
    fz_floor = 0.02 * max(1e-9, float(np.max(wrench[:, 2], initial=0.0)))
    picks = spread(len(train), TRAIN_FRAMES)
    log(f"baselines: mean frame and mean contact of {len(picks)} training frames")
    total = np.zeros((size, size, 3))
    contact, touching = np.zeros((size, size, 3), np.float32), 0
    for i in picks:
        it = train[int(i)]
        frame = uint8_tensor_to_image(it["tactile"]).astype(np.float32)
        total += frame
        run = int(it["run"])
        if wrench[i, 2] > fz_floor:
            dx, dy, theta = _pose_px(pose[i], _scale(train, run, size))
            change = frame - backgrounds[run]
            contact += _move(_move(change, -dx, -dy, 0.0), 0.0, 0.0, -theta)  # the pose to the centre, upright
            touching += 1
    mean_frame = np.clip(total / len(picks), 0, 255).round().astype(np.uint8)
    mean_contact = contact / max(1, touching)
    objects = [str(r.get("object", "")) for r in train.manifest["runs"]]
    train_objects = np.array([objects[int(r)] for r, _ in train.rows])
    w_std = np.where(wrench.std(axis=0) > 1e-9, wrench.std(axis=0), 1.0)
    p_std = np.where(pose.std(axis=0) > 1e-9, pose.std(axis=0), 1.0)
    out: dict[str, list[np.ndarray]] = {name: [] for name in NAMES}
    for it in items:
        run = int(it["run"])
        bg = backgrounds[run]
        w = it["wrench"].numpy() * train.std + train.mean
        p = it["pose"].numpy().astype(np.float64)
        out[BACKGROUND].append(bg)
        out[MEAN_FRAME].append(mean_frame)
        if w[2] > fz_floor and touching:
            dx, dy, theta = _pose_px(p, _scale(train, run, size))
            placed = _move(_move(mean_contact, 0.0, 0.0, theta), dx, dy, 0.0)
            out[PASTED].append(np.clip(bg + placed, 0, 255).round().astype(np.uint8))
        else:
            out[PASTED].append(bg)
        same = train_objects == objects[run]
        pool = np.nonzero(same)[0] if same.any() else np.arange(len(train))
        d = (((wrench[pool] - w) / w_std) ** 2).sum(axis=1)
        d += (((pose[pool][:, [0, 1, 3]] - p[[0, 1, 3]]) / p_std[[0, 1, 3]]) ** 2).sum(axis=1)
        nearest = int(pool[int(np.argmin(d))])
        out[NEAREST].append(uint8_tensor_to_image(train[nearest]["tactile"]))
    return out


def _rows(path: str) -> tuple[np.ndarray, np.ndarray]:
    with RunReader.open(path) as f:
        return f.rows[S.WRENCH], f.rows[S.POSE_MEASURED]
