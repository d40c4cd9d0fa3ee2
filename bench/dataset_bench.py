"""Reading throughput of the training Dataset: samples/s through a DataLoader.

    .venv/bin/python bench/dataset_bench.py [--split DIR] [--workers 4] [--size 256] [--samples 4000]

Without --split it writes a synthetic 3000-frame run (random 256×256 frames) and an
8:2 split of it in a temporary folder. Each sample: a frame read from HDF5, the
object image placed at the frame's pose, the wrench normalised, tensors made.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np


def synthetic_split(tmp: Path) -> Path:
    from acquisition import schema as S
    from acquisition.run_file import RunHeader, RunWriter
    from dataset.split import make_split
    from objects.indenters import get_indenter
    from protocols.plan import PHASES

    rng = np.random.default_rng(0)
    frames = rng.integers(0, 256, (32, 256, 256, 3), dtype=np.uint8)
    header = RunHeader("bench", "", "", "sphere10mm", "", "rgb", 14 / 256, 1.0, 3000, (0, 0, 0, 0), PHASES)
    obj = get_indenter("sphere10mm").object_image(256, 14 / 256)
    w = RunWriter.create(tmp / "bench.h5", header, (256, 256, 3), obj, frames[0])
    row = S.blank_row()  # every per-frame field of the table: a field added there needs nothing here
    for i in range(3000):
        row |= {
            S.WRENCH: rng.normal(size=6),
            S.T_FRAME: float(i),
            S.T_CAPTURE: float(i),
            S.CAPTURE_INDEX: i,
            S.POSE_MEASURED: np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), -1.0, rng.uniform(0, 5)]),
        }
        w.append(frames[i % 32], **row)
    w.set_status("complete")
    w.close()
    make_split([tmp / "bench.h5"], "8:2", tmp / "split")
    return tmp / "split"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--split", type=Path)
    ap.add_argument("--workers", type=int, default=4)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--samples", type=int, default=4000)
    args = ap.parse_args()
    import torch
    from torch.utils.data import DataLoader

    from dataset.torch_dataset import TactileDataset

    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        split = args.split or synthetic_split(Path(tmp))
        ds = TactileDataset(split, "train", size=args.size)
        print(
            f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"torch {torch.__version__}\n"
        )
        print("| workers | size | batch | samples/s | MB/s of frames |\n|---|---|---|---|---|")
        for workers in sorted({0, args.workers}):
            loader = DataLoader(
                ds,
                batch_size=args.batch,
                shuffle=True,
                num_workers=workers,
                persistent_workers=workers > 0,
                generator=torch.Generator().manual_seed(0),
            )
            it = iter(loader)
            next(it)  # start the workers before timing
            n, t = 0, time.perf_counter()
            while n < args.samples:
                try:
                    batch = next(it)
                except StopIteration:
                    it = iter(loader)
                    continue
                n += batch["tactile"].shape[0]
            dt = time.perf_counter() - t
            print(f"| {workers} | {args.size} | {args.batch} | {n / dt:.0f} | {n * 256 * 256 * 3 / dt / 1e6:.0f} |")


if __name__ == "__main__":
    main()
