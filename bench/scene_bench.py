"""Per-frame cost of a full tactile scene: contact solve + render, 256×256, with markers.

    .venv/bin/python bench/scene_bench.py

A press/shear/twist path like the protocol's, for three indenters: each frame is a
new pose (cold caches excluded: kernels are built before timing). Prints the median
and p90 wall time of the solve, the render and the whole frame, per indenter and
phase, and what a forces-only frame costs.
"""

from __future__ import annotations

import os
import platform
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from objects.pose import Pose
from sensor_sim.scene import Scene


def path(phase: str, n: int = 12):
    if phase == "press":
        return [Pose(0, 0, -d, 0) for d in np.linspace(0.1, 1.2, n)]
    if phase == "shear":
        return [Pose(x, 0, -1.2, 0) for x in np.linspace(0.0, 2.0, n)]
    return [Pose(0, 0, -1.2, t) for t in np.linspace(0.0, 5.0, n)]


def main() -> None:
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores (one used), Python {platform.python_version()}\n")
    print(
        "| indenter | sensor | phase | solve ms p50 / p90 | render ms p50 | frame ms p50 / p90 | forces-only ms p50 |"
    )
    print("|---|---|---|---|---|---|---|")
    for name in ("sphere10mm", "circle8mm", "heart"):
        for phase in ("press", "shear", "twist"):
            scene = Scene(name, "rgb_markers")
            forces = Scene(name, "rgb_markers")
            scene.frame(Pose(0, 0, -0.2, 0))  # build kernels and the renderer before timing
            forces.frame(Pose(0, 0, -0.2, 0), image=False)
            solve, render, frame, force_only = [], [], [], []
            for pose in path(phase):
                t0 = time.perf_counter()
                result = scene.contact.solve(pose, scene.renderer.needs())
                t1 = time.perf_counter()
                scene.renderer.render(result.fields)
                t2 = time.perf_counter()
                forces.frame(pose, image=False)
                t3 = time.perf_counter()
                solve.append((t1 - t0) * 1e3)
                render.append((t2 - t1) * 1e3)
                frame.append((t2 - t0) * 1e3)
                force_only.append((t3 - t2) * 1e3)
            p90 = lambda v: sorted(v)[int(0.9 * (len(v) - 1))]
            med = statistics.median
            print(
                f"| {name} | rgb_markers | {phase} | {med(solve):.1f} / {p90(solve):.1f} | {med(render):.1f} | "
                f"{med(frame):.1f} / {p90(frame):.1f} | {med(force_only):.1f} |"
            )


if __name__ == "__main__":
    main()
