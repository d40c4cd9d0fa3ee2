"""Run-file frame storage: bytes per frame, write and read rate per lossless codec.

    .venv/bin/python bench/storage_bench.py --real DIR [--frames 200]

Frames are written the way the run writer writes them: one frame per chunk, appended
one at a time with a flush after each, Fletcher-32 checksums on. Read = every frame
read back one at a time (what export and the PyTorch Dataset do). Frame sets:

- real: the PNG frames in ``--real DIR`` (e.g. a folder of GelSight Mini frames), at
  their own size and centre-cropped square and resized to 256×256 as the rig stores them;
- simulated rgb, rgb_markers, white_markers: 256×256 frames of the shipped sensor profile
  as the simulated rig renders them, a sphere pressed 0.2–1.6 mm and sheared, with the
  profile's measured camera noise on.

Each codec's output is checked equal to its input (lossless) before it is timed.
Blosc and Zstd come from hdf5plugin; gzip and lzf are built into h5py.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import cv2
import h5py
import numpy as np

from common.machine import describe


def codecs() -> dict[str, dict]:
    table = {
        "none": {},
        "lzf": {"compression": "lzf"},
        "gzip-1": {"compression": "gzip", "compression_opts": 1},
        "gzip-4": {"compression": "gzip", "compression_opts": 4},
        "gzip-1+shuffle": {"compression": "gzip", "compression_opts": 1, "shuffle": True},
    }
    try:
        import hdf5plugin
    except ImportError:
        print("(hdf5plugin not installed: Blosc and Zstd rows left out)")
        return table
    table |= {
        "blosc-lz4": dict(hdf5plugin.Blosc(cname="lz4", clevel=5, shuffle=hdf5plugin.Blosc.NOSHUFFLE)),
        "blosc-lz4hc": dict(hdf5plugin.Blosc(cname="lz4hc", clevel=5, shuffle=hdf5plugin.Blosc.NOSHUFFLE)),
        "blosc-zstd-1": dict(hdf5plugin.Blosc(cname="zstd", clevel=1, shuffle=hdf5plugin.Blosc.NOSHUFFLE)),
        "blosc-zstd-5": dict(hdf5plugin.Blosc(cname="zstd", clevel=5, shuffle=hdf5plugin.Blosc.NOSHUFFLE)),
        "zstd-3": dict(hdf5plugin.Zstd(clevel=3)),
        # bit planes of uint8 pixels: neighbouring pixels share their high bits, so the
        # shuffled stream has long runs that byte-oriented codecs miss
        "blosc-lz4+bitshuffle": dict(hdf5plugin.Blosc(cname="lz4", clevel=5, shuffle=hdf5plugin.Blosc.BITSHUFFLE)),
        "blosc-zstd-1+bitshuffle": dict(hdf5plugin.Blosc(cname="zstd", clevel=1, shuffle=hdf5plugin.Blosc.BITSHUFFLE)),
        "blosc-zstd-3+bitshuffle": dict(hdf5plugin.Blosc(cname="zstd", clevel=3, shuffle=hdf5plugin.Blosc.BITSHUFFLE)),
        "bitshuffle-lz4": dict(hdf5plugin.Bitshuffle(cname="lz4")),
        "bitshuffle-zstd": dict(hdf5plugin.Bitshuffle(cname="zstd")),
        # image codecs: the pixel predicted from its neighbours, the residual coded
        "htj2k": dict(hdf5plugin.Htj2k()),  # JPEG 2000 (high-throughput), reversible
    }
    return table


def square_256(img: np.ndarray) -> np.ndarray:
    h, w = img.shape[:2]
    s = min(h, w)
    y, x = (h - s) // 2, (w - s) // 2
    return cv2.resize(img[y : y + s, x : x + s], (256, 256), interpolation=cv2.INTER_AREA)


def real_frames(folder: Path) -> list[np.ndarray]:
    frames = [cv2.imread(str(p), cv2.IMREAD_COLOR) for p in sorted(folder.glob("*.png"))]
    frames = [f for f in frames if f is not None]
    if not frames:
        raise SystemExit(f"{folder}: no PNG frames found")
    return frames


def simulated_frames(kind: str, n: int) -> list[np.ndarray]:
    """As the simulated rig draws them: the shipped profile's optics, background and measured
    (spatially correlated) camera noise, through the one render function."""
    from objects.pose import Pose
    from sensor_sim.press_render import PressRender
    from sensor_sim.profile import default_profile

    press = PressRender(default_profile(), "sphere10mm", kind, noise=True, seed=1)
    out = []
    for i in range(n):
        depth = 0.2 + 1.4 * i / max(1, n - 1)
        shear = 0.5 * np.sin(i / 3)
        out.append(press.render(Pose(shear, 0.0, -depth, 2.0 * np.cos(i / 5))))
    return out


def measure(frames: list[np.ndarray], n: int, kwargs: dict, tmp: Path) -> tuple[float, float, float]:
    """(bytes per frame, write frames/s, read frames/s) for ``n`` frames cycled from ``frames``."""
    shape = frames[0].shape
    path = tmp / "codec.h5"
    with h5py.File(path, "w", libver="latest") as f:
        d = f.create_dataset(
            "frames", (0, *shape), maxshape=(None, *shape), chunks=(1, *shape), dtype="u1", fletcher32=True, **kwargs
        )
        f.swmr_mode = True
        t = time.perf_counter()
        for i in range(n):
            d.resize(i + 1, axis=0)
            d[i] = frames[i % len(frames)]
            f.flush()
        write_fps = n / (time.perf_counter() - t)
    size = os.path.getsize(path)
    with h5py.File(path, "r") as f:
        d = f["frames"]
        t = time.perf_counter()
        for i in range(n):
            got = d[i]
            if i < len(frames) and not np.array_equal(got, frames[i]):
                raise SystemExit(f"codec {kwargs} is not lossless")
        read_fps = n / (time.perf_counter() - t)
    path.unlink()
    return size / n, write_fps, read_fps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--real", type=Path, help="folder of real sensor frames (PNG)")
    ap.add_argument("--frames", type=int, default=200, help="frames written per codec and set (default 200)")
    ap.add_argument("--sim-frames", type=int, default=24, help="distinct simulated frames per kind (default 24)")
    args = ap.parse_args()
    print(f"machine: {describe()}, h5py {h5py.version.version}, HDF5 {h5py.version.hdf5_version}\n")
    sets: dict[str, list[np.ndarray]] = {}
    if args.real:
        real = real_frames(args.real)
        sets[f"real {real[0].shape[1]}x{real[0].shape[0]}"] = real
        sets["real 256x256"] = [square_256(f) for f in real]
    for kind in ("rgb", "rgb_markers", "white_markers"):
        sets[f"sim {kind}"] = simulated_frames(kind, args.sim_frames)
    table = codecs()
    print("| frames | codec | KB/frame | ratio to raw | write frames/s | read frames/s |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, frames in sets.items():
            raw = frames[0].nbytes
            for codec, kwargs in table.items():
                per_frame, wfps, rfps = measure(frames, args.frames, kwargs, Path(tmp))
                print(
                    f"| {name} | {codec} | {per_frame / 1e3:.1f} | {per_frame / raw:.3f} | {wfps:.0f} | {rfps:.0f} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
