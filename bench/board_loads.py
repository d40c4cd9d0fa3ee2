"""The loads a texture board reaches along the paper's press/shear/twist sequence on the
simulated rig, and the [limits] its protocol file should declare.

A board presses the whole gel, so its force is the gel's stiffness over the whole contact
area, not a sphere's few square millimetres: at the paper's 0.4 mm steps to 1.6 mm the
simulated GelSight Mini gel pushes back tens of newtons, where a 10 mm sphere gives 7 N.
This runs each board's protocol (the paper's sequence, its speeds ×100 and one capture every
5 s: the contact is quasi-static, as tests/test_library_on_sim.py runs it) with the guard at
the gauge's full scale, and prints the peak |load| per component and level, the contact
area at the deepest press, the stiffness that implies (N per mm of depth per mm² of contact),
and limits = 1.3 × peak rounded up: the margin covers another board's relief and the
simulator's error on a real gel (docs/protocols.md, "Texture boards").

    .venv/bin/python bench/board_loads.py [woven irregular dots]
"""

from __future__ import annotations

import dataclasses
import math
import platform
import re
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from acquisition import schema as S  # noqa: E402
from acquisition.executor import Acquisition  # noqa: E402
from cli.simulated import monitor_interval_s, simulated_rig_for  # noqa: E402
from common.gauge_range import MAX_FORCE_LIMIT_N, MAX_TORQUE_LIMIT_NMM  # noqa: E402
from protocols.plan import Plan  # noqa: E402
from protocols.spec import load_protocol  # noqa: E402
from rig.config import SafetyConfig  # noqa: E402

MARGIN = 1.3
COMPONENTS = ("Fx N", "Fy N", "Fz N", "Mx N·mm", "My N·mm", "Mz N·mm")


PAPER = ["motion.depth_step_mm=0.4", "motion.max_depth_mm=1.6"]  # the paper's sequence, whatever the file says


def fast_protocol(name: str, folder: Path):
    text = load_protocol(name, PAPER).text
    text = re.sub(r"(?m)^speed_mm_s = [0-9.]+", "speed_mm_s = 1.0", text)
    text = re.sub(r"(?m)^twist_speed_deg_s = [0-9.]+", "twist_speed_deg_s = 5.0", text)
    text = re.sub(r"(?m)^rate_hz = [0-9.]+", "rate_hz = 0.2", text)
    text = re.sub(r"(?ms)^\[limits\].*?(?=^\[|\Z)", "", text)  # measure without the file's own limits
    path = folder / f"{name}.toml"
    path.write_text(text)
    return load_protocol(path)


def measure(name: str, folder: Path) -> dict:
    protocol = fast_protocol(name, folder)
    out = folder / f"{name}.h5"
    t0 = time.perf_counter()
    with simulated_rig_for(protocol) as (rig, sim, header):
        full = dataclasses.replace(
            rig.config.safety,
            max_force_N=(MAX_FORCE_LIMIT_N,) * 3,
            max_torque_Nmm=(MAX_TORQUE_LIMIT_NMM,) * 3,
        )
        assert isinstance(full, SafetyConfig)
    with simulated_rig_for(protocol, safety=full) as (rig, sim, header):
        result = Acquisition(rig, Plan.of(protocol), monitor_interval_s=monitor_interval_s(protocol)).run(
            out, header=header
        )
        contact = sim.world.contact
    seconds = time.perf_counter() - t0
    with h5py.File(out, "r") as f:
        stream = f[S.WRENCH_STREAM][()] if S.WRENCH_STREAM in f else None
        wrench = f[S.WRENCH][()]
    loads = np.abs(stream[:, 1:7] if stream is not None and stream.shape[1] >= 7 else wrench)
    deepest = protocol.levels[-1]
    from objects.pose import Pose

    solved = contact.solve(Pose(0.0, 0.0, -deepest, 0.0))
    area_mm2 = solved.normal.contact_area_mm2 if solved.normal is not None else math.nan
    peak = loads.max(axis=0)
    return {
        "name": name,
        "status": result.status,
        "peak": peak,
        "area_mm2": area_mm2,
        "stiffness": peak[2] / deepest / area_mm2 if area_mm2 > 0 else math.nan,
        "limits": [math.ceil(MARGIN * v) for v in peak],
        "seconds": seconds,
        "levels": protocol.levels,
    }


def main(names: list[str]) -> None:
    print(f"machine: {platform.processor() or platform.machine()}, {__import__('os').cpu_count()} cores")
    print("| board | status | " + " | ".join(f"peak {c}" for c in COMPONENTS) + " | area mm² | N/(mm·mm²) | s |")
    print("|---" * (len(COMPONENTS) + 5) + "|")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            r = measure(name, Path(tmp))
            rows.append(r)
            print(
                f"| {name} | {r['status']} | "
                + " | ".join(f"{v:.1f}" for v in r["peak"])
                + f" | {r['area_mm2']:.0f} | {r['stiffness']:.3f} | {r['seconds']:.0f} |",
                flush=True,
            )
    print("\nlimits to declare (1.3 × peak, rounded up):")
    for r in rows:
        f, m = r["limits"][:3], r["limits"][3:]
        print(f"{r['name']}: max_force_N = {f}   max_torque_Nmm = {m}")


if __name__ == "__main__":
    main(sys.argv[1:] or ["woven", "irregular"])
