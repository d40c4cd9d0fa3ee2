"""Milliseconds per frame of ``Renderer.render``, this tree against an older commit's renderer.

    .venv/bin/python bench/render_bench.py [--old 9c34a2e] [--rounds 15]

The old renderer is that commit's ``sensor_sim/optics.py`` and ``sensor_sim/light.py``
(``git show``), loaded beside this tree's. Per sensor kind (the shipped profile, 256 × 256,
noise on), both render the same fields of sphere10mm along a press, shear and twist path,
in turns (old, new, old, new, ...) so that both see the same machine load; every frame
is checked to be the same bytes. Two cases: every frame a new contact (the renderer's
work in full), and each contact rendered twice in a row (a slow protocol's frames, where
the solve's pose cache hands the camera the same fields). Prints a table of the median
ms per frame and old / new.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common.machine import describe  # noqa: E402
from common.sensors import SENSOR_KINDS  # noqa: E402
from objects.pose import Pose  # noqa: E402
from sensor_sim.optics import Renderer  # noqa: E402
from sensor_sim.profile import default_profile  # noqa: E402
from sensor_sim.scene import Scene  # noqa: E402

OLD = "9c34a2e"  # the renderer before the planar rewrite


def old_renderer_class(commit: str, tmp: Path):
    """``commit``'s Renderer, its light module loaded as ``_old_light``."""

    def load(name: str, path: str, replace: tuple[str, str] | None = None):
        text = subprocess.run(
            ["git", "show", f"{commit}:{path}"], cwd=ROOT, check=True, capture_output=True, text=True
        ).stdout
        if replace:
            text = text.replace(*replace)
        file = tmp / f"{name}.py"
        file.write_text(text)
        spec = importlib.util.spec_from_file_location(name, file)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        return module

    light = load("_old_light", "sensor_sim/light.py")
    optics = load("_old_optics", "sensor_sim/optics.py", ("from sensor_sim.light import", "from _old_light import"))
    return light, optics.Renderer


def poses() -> list[Pose]:
    press = [Pose(0, 0, -d, 0) for d in np.linspace(0.2, 1.2, 6)]
    shear = [Pose(x, 0, -1.0, 0) for x in np.linspace(0.1, 1.0, 6)]
    twist = [Pose(0.5, 0, -1.0, t) for t in np.linspace(0.5, 4.0, 6)]
    return press + shear + twist


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", default=OLD, help="the commit whose renderer is the old one")
    parser.add_argument("--rounds", type=int, default=15, help="timed rounds per kind and case (median)")
    args = parser.parse_args()
    profile = default_profile()
    print(f"machine: {describe()}; load {os.getloadavg()[0]:.2f}")
    print(f"old: {args.old}'s renderer; new: this tree's; 256 × 256, noise on, {len(poses())} contacts\n")
    print("| kind | frames rendered | old ms / frame | new ms / frame | old / new |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="render-bench-") as tmp:
        old_light, OldRenderer = old_renderer_class(args.old, Path(tmp))
        for kind in SENSOR_KINDS:
            scene = Scene("sphere10mm", kind)
            spec = profile.optics_spec(kind)
            new = Renderer(spec, scene.geometry, seed=3, profile=profile)
            old = OldRenderer(spec, scene.geometry, seed=3, profile=profile)
            old.light = old_light.LightModel(  # the old light model's own code, same numbers
                profile.light.table_bgr, profile.light.blur_mm, profile.light.shading, profile.light.reference_bgr
            )
            fields = [scene.contact.solve(pose, new.needs()).fields for pose in poses()]
            for case, sequence in (
                ("new contact each", fields),
                ("each contact twice", [f for f in fields for _ in (0, 1)]),
            ):
                times: dict[str, list[float]] = {"old": [], "new": []}
                for _ in range(args.rounds):
                    for name, renderer in (("old", old), ("new", new)):
                        t0 = time.perf_counter()
                        for f in sequence:
                            renderer.render(f)
                        times[name].append((time.perf_counter() - t0) / len(sequence) * 1e3)
                for f in sequence:  # same seed, same draws so far: the same frames
                    assert np.array_equal(old.render(f), new.render(f)), f"{kind}: frames differ"
                t_old, t_new = statistics.median(times["old"]), statistics.median(times["new"])
                print(f"| {kind} | {case} | {t_old:.2f} | {t_new:.2f} | {t_old / t_new:.2f}× |")
    print(f"\nload at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
