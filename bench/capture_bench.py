"""Capture timing on the simulated rig in real time, and the run writer's top rate.

    .venv/bin/python bench/capture_bench.py [--seconds 30] [--frames 1500]

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
    text = (base.replace("max_depth_mm = 1.6", "max_depth_mm = 0.4").replace("speed_mm_s = 0.01", "speed_mm_s = 0.05")
            .replace("shear_mm = 2.0", "shear_mm = 0.25").replace("twist_deg = 5.0", "twist_deg = 1.0"))
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
    print(f"real-time run: {result.frames} frames at 1 Hz ({plan.captured_duration_s:.0f} s captured, {wall:.0f} s wall), "
          f"status {result.status}\n")
    print("| measure | p50 ms | p99 ms | max ms |\n|---|---|---|---|")
    print(f"| trigger jitter (frame time − scheduled) | {pct(jitter, .5):.2f} | {pct(jitter, .99):.2f} | {max(jitter):.2f} |")
    print(f"| wrench–frame skew | {pct(skew, .5):.2f} | {pct(skew, .99):.2f} | {max(skew):.2f} |")


def writer(frames: int) -> None:
    rng = np.random.default_rng(0)
    images = rng.integers(0, 256, (16, 256, 256, 3), dtype=np.uint8)
    header = RunHeader("bench", "", "", "sphere10mm", "", "rgb", 14 / 256, 1.0, frames, (0, 0, 0, 0), PHASES)
    row = {"wrench": np.zeros(6), "pose_commanded": np.zeros(4), "pose_measured": np.zeros(4), "t_frame_s": 0.0,
           "t_capture_s": 0.0, "wrench_skew_s": 0.0, "capture_index": 0, "step_index": 0, "phase_index": 0, "level": 0}
    with tempfile.TemporaryDirectory() as tmp:
        w = RunWriter.create(Path(tmp) / "w.h5", header, (256, 256, 3), images[0], images[0])
        t = time.perf_counter()
        for i in range(frames):
            row["capture_index"] = i
            w.append(images[i % 16], **row)
        dt = time.perf_counter() - t
        w.close()
    mb = frames * 256 * 256 * 3 / 1e6
    print(f"\nwriter: {frames} frames of 256x256x3, flushed per frame (SWMR): {frames / dt:.0f} frames/s, "
          f"{mb / dt:.0f} MB/s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=1500)
    args = ap.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}\n")
    timing(0)
    writer(args.frames)


if __name__ == "__main__":
    main()
