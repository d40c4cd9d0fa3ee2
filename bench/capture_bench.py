"""Capture timing on the simulated rig in real time, and the run writer's top rate.

    .venv/bin/python bench/capture_bench.py [--frames 1500] [--writer-only]

1. A protocol run on the simulated rig with the real clock (not the discrete-event
   clock `rig run-protocol --sim` uses): trigger jitter = frame timestamp − scheduled
   capture time, against the 1 s period; wrench–frame skew = distance from the frame
   timestamp to the nearest gauge sample (FT300 stream at 100 Hz).
2. The HDF5 run writer alone: 256×256×3 frames appended and flushed one by one.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from acquisition import schema as S
from acquisition.executor import Acquisition
from acquisition.run_file import RunHeader, RunWriter
from protocols.plan import PHASES, Plan
from protocols.spec import load_protocol, parse_protocol
from rig.clock import SystemClock
from rig.rig import Rig
from rig.sim.rig_sim import SimulatedRig


def pct(values, q):
    v = sorted(values)
    return v[min(len(v) - 1, int(q * len(v)))]


def timing(seconds: float) -> None:
    base = load_protocol("sphere10mm").text
    text = (
        base.replace("max_depth_mm = 1.6", "max_depth_mm = 0.4")
        .replace("speed_mm_s = 0.01", "speed_mm_s = 0.05")
        .replace("shear_mm = 2.0", "shear_mm = 0.25")
        .replace("twist_deg = 5.0", "twist_deg = 1.0")
    )
    protocol = parse_protocol(text, "bench.toml")
    plan = Plan.of(protocol)
    clock = SystemClock()
    with tempfile.TemporaryDirectory() as tmp, SimulatedRig(clock, sensor_kind="rgb") as sim:
        sim.triggered_camera = True
        with Rig.open(sim.config(), clock, camera=True, sim=sim) as rig:
            acq = Acquisition(rig, plan, monitor_interval_s=0.02)
            t = time.perf_counter()
            result = acq.run(Path(tmp) / "t.h5", header={"rig_config": "bench", "mm_per_px": 14 / 256})
            wall = time.perf_counter() - t
    jitter = [1e3 * x for x in result.trigger_lag_s]
    skew = [1e3 * x for x in result.skews_s]
    print(
        f"real-time run: {result.frames} frames at 1 Hz "
        f"({plan.captured_duration_s:.0f} s captured, {wall:.0f} s wall), "
        f"status {result.status}\n"
    )
    print("| measure | p50 ms | p99 ms | max ms |\n|---|---|---|---|")
    print(
        f"| trigger jitter (frame time − scheduled) | {pct(jitter, 0.5):.2f} | {pct(jitter, 0.99):.2f} "
        f"| {max(jitter):.2f} |"
    )
    print(f"| wrench–frame skew | {pct(skew, 0.5):.2f} | {pct(skew, 0.99):.2f} | {max(skew):.2f} |")


def simulated_images(n: int) -> np.ndarray:
    from objects.pose import Pose
    from sensor_sim.scene import Scene

    scene = Scene("sphere10mm", "rgb", seed=1)
    return np.stack([scene.frame(Pose(0.3 * np.sin(i), 0.0, -0.2 - 1.4 * i / n, 0.0)).image for i in range(n)])


def writer(frames: int, images: np.ndarray, what: str, codec: str | None) -> None:
    header = RunHeader("bench", "", "", "sphere10mm", "", "rgb", 14 / 256, 1.0, frames, (0, 0, 0, 0), PHASES)
    row = S.blank_row()  # every per-frame field of the table: a field added there needs nothing here
    with tempfile.TemporaryDirectory() as tmp:
        w = RunWriter.create(
            Path(tmp) / "w.h5", header, (256, 256, 3), images[0], images[0], compress=codec is not None, codec=codec
        )
        t = time.perf_counter()
        for i in range(frames):
            row[S.CAPTURE_INDEX] = i
            w.append(images[i % len(images)], **row)
        dt = time.perf_counter() - t
        w.close()
        size = (Path(tmp) / "w.h5").stat().st_size
    print(f"| {what} | {codec or 'none'} | {frames / dt:.0f} | {size / frames / 1e3:.1f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=1500)
    ap.add_argument("--writer-only", action="store_true", help="skip the real-time run (part 1)")
    args = ap.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}\n")
    if not args.writer_only:
        timing(0)
    print(f"\nwriter: {args.frames} frames of 256x256x3, flushed one by one (SWMR)\n")
    print("| frames | codec | frames/s | KB/frame on disk |\n|---|---|---|---|")
    rng = np.random.default_rng(0)
    for what, images in (
        ("simulated rgb", simulated_images(16)),
        ("random (incompressible)", rng.integers(0, 256, (16, 256, 256, 3), dtype=np.uint8)),
    ):
        for codec in (None, *S.FRAME_CODECS):
            writer(args.frames, images, what, codec)


if __name__ == "__main__":
    main()
