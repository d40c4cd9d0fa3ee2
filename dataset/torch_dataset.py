"""A PyTorch Dataset over a split: (condition image, wrench, tactile image).

Imports torch: used by training only, never by the other `dataset` commands. Before anything
is read, every run file is compared with the identity the split recorded when it verified it
(dataset/split_manifest.py): a file changed since is refused, naming it. Run files are opened
lazily in each worker process (h5py handles do not survive fork) through the verified reader
(acquisition/run_reader.py: rows checked at open, each frame's checksum as it is read, a damaged
one named with its file and frame), and kept open for the worker's life. Besides the model's inputs, an
item carries any per-frame fields of the run-file table asked for (``fields=``), so a
field added to the table reaches training without touching this module, and the physics
render of each frame when a cache of them is given (``physics=``, model/conditioning/physics_condition.py).
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import torch
from torch.utils.data import Dataset

from acquisition import schema as S
from acquisition.run_reader import RunReader
from dataset.condition import condition_image, normalise_wrench
from dataset.split_manifest import check_unchanged, load_split


def image_to_tensor(bgr: np.ndarray) -> torch.Tensor:
    """(H, W, 3) BGR uint8 → (3, H, W) RGB uint8."""
    return torch.from_numpy(np.ascontiguousarray(bgr[..., ::-1].transpose(2, 0, 1)))


def scale_images(images: torch.Tensor) -> torch.Tensor:
    """uint8 0–255 → float in [−1, 1]."""
    return images.float().div_(127.5).sub_(1.0)


def tensor_to_image(image: torch.Tensor) -> np.ndarray:
    """(3, H, W) RGB in [−1, 1] → (H, W, 3) BGR uint8."""
    rgb = ((image.detach().cpu().numpy().transpose(1, 2, 0) + 1) * 127.5).round().clip(0, 255).astype(np.uint8)
    return np.ascontiguousarray(rgb[..., ::-1])


def uint8_tensor_to_image(image: torch.Tensor) -> np.ndarray:
    """(3, H, W) RGB uint8 (a Dataset item's image) → (H, W, 3) BGR uint8."""
    return np.ascontiguousarray(image.numpy().transpose(1, 2, 0)[..., ::-1])


def spread(length: int, n: int | None) -> np.ndarray:
    """Indices of ``n`` items spread evenly over ``length`` (all of them when ``n`` is None)."""
    n = length if n is None else min(n, length)
    return np.unique(np.linspace(0, length - 1, n).round().astype(int))


def condition_of(batch: dict) -> torch.Tensor:
    """The model's condition channels of an item or a collated batch (uint8): the object image,
    then the physics render when the item carries one (3 or 6 channels)."""
    if "physics" not in batch:
        return batch["condition"]
    return torch.cat([batch["condition"], batch["physics"]], dim=-3)


def to_model_inputs(batch: dict, device=None) -> dict:
    """uint8 images → float in [−1, 1] on ``device`` (the GPU, in training): 4× less data
    crosses from the loader's workers than if they sent floats."""
    out = dict(batch)
    for key in ("condition", "tactile", "physics"):
        if key in batch:
            out[key] = scale_images(batch[key].to(device, non_blocking=True))
    out["wrench"] = batch["wrench"].to(device, non_blocking=True)
    return out


class TactileDataset(Dataset):
    """Items: dict(condition (3, s, s) uint8, wrench (6,) float32 normalised with the training
    part's statistics, tactile (3, s, s) uint8, pose (4,), run, frame). Images are RGB;
    ``to_model_inputs`` scales them to [−1, 1]. ``fields``: per-frame fields of the run-file
    table (acquisition/schema.py) added to each item under their names, as tensors; a run
    written before an optional field existed serves its fill value. ``physics``: a cache of the
    part's physics renders (model/conditioning/physics_condition.py's ``physics_cache``, a .npy of
    (frames, size, size, 3) BGR uint8 in row order) served as ``physics`` (3, s, s) RGB uint8.
    Each item also names its run file (``run_path``)."""

    def __init__(
        self,
        split_dir: str | Path,
        part: str = "train",
        size: int = 256,
        fields: tuple[str, ...] = (),
        physics: str | Path | None = None,
    ):
        self.manifest, parts = load_split(split_dir)
        check_unchanged(self.manifest, split_dir)
        if part not in parts:
            raise KeyError(f"{split_dir}: no part {part!r}; it has {', '.join(parts)}")
        table = {f.path: f for f in S.PER_FRAME_FIELDS}
        unknown = [name for name in fields if name not in table]
        if unknown:
            raise KeyError(
                f"fields {', '.join(unknown)}: not per-frame fields of the run-file table ({', '.join(table)})"
            )
        self.fields = tuple(table[name] for name in fields)
        self.rows = parts[part]
        self.size = size
        self.runs = [r["path"] for r in self.manifest["runs"]]
        self.mm_per_px = [float(r["mm_per_px"]) for r in self.manifest["runs"]]
        self.mean = np.asarray(self.manifest["wrench_mean"])
        self.std = np.asarray(self.manifest["wrench_std"])
        self.physics = None if physics is None else self._physics(Path(physics), part)
        self._files: dict[int, RunReader] = {}
        self._pid: int | None = None

    def _physics(self, path: Path, part: str) -> np.ndarray:
        """The cache's images, memory-mapped, after checking they are this part's at this size."""
        import hashlib
        import json

        expected = (len(self.rows), self.size, self.size, 3)
        try:
            key = json.loads(path.with_suffix(".json").read_text())
            images = np.load(path, mmap_mode="r")
        except (OSError, ValueError) as exc:
            raise ValueError(f"{path}: not a physics render cache ({exc}); rebuild it with `train`") from None
        rows_sha1 = hashlib.sha1(np.ascontiguousarray(self.rows).tobytes()).hexdigest()
        if images.shape != expected or images.dtype != np.uint8 or key.get("rows_sha1") != rows_sha1:
            raise ValueError(
                f"{path}: physics renders {images.shape} {images.dtype} are not the {part} part's "
                f"{expected} uint8 (a stale cache); rebuild it with `train`"
            )
        return images

    def __len__(self) -> int:
        return len(self.rows)

    def _file(self, run: int) -> RunReader:
        if self._pid != os.getpid():  # a fresh worker: handles from the parent are not ours
            self._files, self._pid = {}, os.getpid()
        if run not in self._files:
            self._files[run] = RunReader.open(self.runs[run])  # verified; bounded retries: never hangs
        return self._files[run]

    def _to_tensor(self, bgr: np.ndarray) -> torch.Tensor:
        if bgr.shape[0] != self.size:
            bgr = cv2.resize(bgr, (self.size, self.size), interpolation=cv2.INTER_AREA)
        return image_to_tensor(bgr)

    def __getitem__(self, i: int) -> dict:
        run, frame = (int(v) for v in self.rows[i])
        f = self._file(run)
        tactile = f.frame(frame)
        wrench = f.rows[S.WRENCH][frame]
        pose = f.rows[S.POSE_MEASURED][frame]
        obj = f.image(S.OBJECT_IMAGE)
        condition = condition_image(obj, pose[0], pose[1], pose[3], self.mm_per_px[run], tactile.shape[1], self.size)
        extra = {fl.path: torch.from_numpy(np.asarray(f.rows[fl.path][frame], dtype=fl.dtype)) for fl in self.fields}
        if self.physics is not None:
            extra["physics"] = image_to_tensor(np.asarray(self.physics[i]))
        return extra | {
            "run_path": self.runs[run],
            "condition": image_to_tensor(condition),
            "wrench": torch.from_numpy(normalise_wrench(wrench, self.mean, self.std).astype(np.float32)),
            "tactile": self._to_tensor(tactile),
            "pose": torch.from_numpy(pose.astype(np.float32)),
            "run": run,
            "frame": frame,
        }
