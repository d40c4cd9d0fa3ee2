"""Does the speed envelope hold still on a loaded machine? (docs/safety.md, "A speed envelope that
does not wobble")

    .venv/bin/python bench/envelope_stability.py [--runs 10] [--baseline-tree DIR]

1. `rig status --sim` RUNS times on idle cores and RUNS times with both cores kept busy by two
   other processes: the gauge period it measured and the z speed it allows in contact, min /
   median / max — for this tree and, with ``--baseline-tree``, for another checkout's `rig` in
   the same run (e.g. `git worktree add /tmp/base COMMIT`, set up with scripts/setup.sh).
2. The guard loop itself: a 0.6 mm press at 0.2 mm/s on the simulated rig in real time, in this
   process; the gap between the session's successive checks (its configured period is 20 ms),
   idle and loaded: median, 90th percentile, worst.
"""

from __future__ import annotations

import argparse
import contextlib
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common.machine import describe  # noqa: E402

BUSY = "while True: pass"


@contextlib.contextmanager
def load(on: bool):
    """Both cores busy with two other processes while the block runs (nothing when ``on`` is False)."""
    hogs = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(2 if on else 0)]
    try:
        yield
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()


def status_once(rig: str) -> tuple[float, float]:
    out = subprocess.run([rig, "status", "--sim"], capture_output=True, text=True, timeout=120).stdout
    period = float(re.search(r"gauge sample period ([0-9.]+) ms", out).group(1))
    cap = float(re.search(r"speed envelope in contact: .*?z ([0-9.e-]+) mm/s", out).group(1))
    return period, cap


def spread(values: list[float]) -> str:
    return f"{min(values):7.1f} {statistics.median(values):7.1f} {max(values):7.1f}"


def spread3(values: list[float]) -> str:
    return f"{min(values):7.3f} {statistics.median(values):7.3f} {max(values):7.3f}"


def guard_gaps(loaded: bool) -> list[float]:
    """Seconds between the checks of one press on the real-time simulated rig."""
    from rig.motion import Motion
    from rig.rig import Rig
    from rig.sim.rig_sim import SimulatedRig
    from rig.sim.world import WorldSpec

    spec = WorldSpec()
    spec.start["z"] = spec.geometry["z"].origin - 0.1
    stamps: list[float] = []
    original = Motion.monitor

    def monitor(self, *args, **kwargs):
        stamps.append(time.monotonic())
        return original(self, *args, **kwargs)

    with load(loaded), SimulatedRig(spec=spec) as sim:
        rig = Rig.open(sim.config(with_camera=False), sim.clock, axes=("z",))
        try:
            rig.tare(20)
            Motion.monitor = monitor  # type: ignore[method-assign]
            with rig.motion("press", on_note=lambda text: None) as m:
                m.move({"z": -0.5}, 0.2)
        finally:
            Motion.monitor = original  # type: ignore[method-assign]
            rig.close()
    return [b - a for a, b in zip(stamps, stamps[1:])]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--baseline-tree", type=Path)
    args = parser.parse_args()
    trees = {"this tree": str(Path(sys.executable).parent / "rig")}
    if args.baseline_tree:
        trees[f"baseline {args.baseline_tree}"] = str(args.baseline_tree / ".venv" / "bin" / "rig")
    print(f"machine: {describe()}")
    print(f"`rig status --sim`, {args.runs} runs each: gauge period (ms) and z in contact (mm/s), min median max")
    print(f"{'tree':32s} {'cores':6s} {'period ms':>23s}   {'z cap mm/s':>23s}")
    for name, rig in trees.items():
        for loaded in (False, True):
            with load(loaded):
                results = [status_once(rig) for _ in range(args.runs)]
            periods, caps = [p for p, _ in results], [c for _, c in results]
            print(f"{name:32s} {'busy' if loaded else 'idle':6s} {spread(periods)}   {spread3(caps)}")
    print("\nthe guard loop (checks every 20 ms) during a 0.5 mm press at 0.2 mm/s, real time, gaps in ms")
    print(f"{'cores':6s} {'checks':>6s} {'median':>7s} {'p90':>7s} {'worst':>7s}")
    for loaded in (False, True):
        gaps = sorted(1000 * g for g in guard_gaps(loaded))
        p90 = gaps[int(0.9 * (len(gaps) - 1))]
        cores = "busy" if loaded else "idle"
        print(f"{cores:6s} {len(gaps):6d} {statistics.median(gaps):7.1f} {p90:7.1f} {gaps[-1]:7.1f}")


if __name__ == "__main__":
    main()
