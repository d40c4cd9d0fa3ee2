"""What protects the sensor when the process driving a press stops answering (docs/safety.md).

    .venv/bin/python bench/host_failure_bench.py [--quick] [--freeze-s 60] [--out FILE]

Each case: the simulators `rig sim serve` runs (the Zaber chain, the PR drive, an FT300 at 10 or
100 Hz, a sphere10mm or a rigid plate20mm), served on ptys from this process so that it can read
the simulated world's true pose; a `rig jog --axis z --to FLOOR --speed V --config CFG --object
OBJ` in its own process, started 1.6 mm above the gel; and, at the moment the indenter first
touches the gel (the world's z crosses the true surface, before the gauge or the host can have
seen anything) or, with ``--at half``, once the true load is half the limit, that process is

- ``freeze``: stopped with SIGSTOP until the z stage has been at rest for 0.5 s (at most
  ``--freeze-s``, 60 s by default; a stage at rest goes nowhere, so waiting longer changes
  nothing), then continued with SIGCONT and left to finish; or
- ``kill``: killed with SIGKILL; when z has come to rest, `rig status` opens the rig again.

The remembered gel surface is written into the rig's state beforehand: ``right`` (the true
surface), ``0.5 low`` and ``1 low`` (a surface measured before a longer indenter or a thicker gel
went on, which the rig has no way to know), and ``other`` (measured with another indenter: the
command names its own). The target is the depth floor as the rig computes it from what it
remembers (for ``other``, from the other indenter's surface): the deepest `rig jog` allows.
The Fz limit is 10 N for the plate (met 0.17 mm into the gel: the force bound decides) and the
simulated rig's own 40 N for the sphere (not reached above the floor: the depth bound decides).

Measured by the simulator, never by the rig: the true peak Fz (the contact solver at the deepest
z the indenter reached) ÷ the limit, and how far that deepest z is below the true depth floor
(the true surface − 60 % of the 3 mm gel; negative: above it). Also whether z's controller
limits were back to their own after the case (restored by the process itself, or by the next
command after a kill). The last line is ``worst peak/limit: X  deepest below floor: Y mm``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common.machine import describe  # noqa: E402

FAILURES = ("freeze", "kill")
SPEEDS = (0.1, 1.0, 5.0)
OBJECTS = ("sphere10mm", "plate20mm")
MOMENTS = ("touch", "half")  # the process fails as the indenter touches, or once the true load is half the limit
GAUGES_HZ = (10.0, 100.0)
SURFACES = {"right": 0.0, "0.5 low": -0.5, "1 low": -1.0, "other": -1.0}  # remembered surface, axis z
OTHER_INDENTER = "sphere4mm"
TRUE_SURFACE_MM = 0.0  # the simulated gel's surface in axis z
START_ABOVE_MM = 1.6  # just above where full speed ends for the right surface (+1.5 mm)
GEL_MM = 3.0
FRACTION = 0.6
PLATE_LIMIT_N = 10.0
SPHERE_LIMIT_N = 40.0
REST_S = 0.5
RIG = str(Path(sys.executable).parent / "rig")


@dataclasses.dataclass
class Case:
    failure: str
    speed: float
    obj: str
    gauge_hz: float
    surface: str
    moment: str = "touch"


@dataclasses.dataclass
class Outcome:
    case: Case
    limit_N: float
    peak_N: float
    below_floor_mm: float
    frozen_s: float
    restored: bool
    touched: bool
    said: str

    @property
    def ratio(self) -> float:
        return self.peak_N / self.limit_N


class Loads:
    """The simulated contact's true Fz at a depth, per object (a solver of its own)."""

    def __init__(self):
        self._contacts = {}

    def fz(self, obj: str, z_mm: float) -> float:
        from objects.pose import Pose
        from rig.clock import ManualClock
        from rig.sim.rig_sim import SimulatedRig

        if obj not in self._contacts:
            sim = SimulatedRig(ManualClock(), indenter=obj)
            self._contacts[obj] = sim.world.contact
            sim.close()
        contact = self._contacts[obj]
        contact.reset()
        return float(contact.wrench(Pose(0.0, 0.0, min(z_mm, 0.0), 0.0))[2])


def depth_for(obj: str, load_N: float, loads: Loads) -> float:
    """The depth (mm, > 0) at which the true Fz first reaches ``load_N`` (bisection)."""
    low, high = 0.0, FRACTION * GEL_MM
    for _ in range(30):
        mid = (low + high) / 2
        low, high = (mid, high) if loads.fz(obj, TRUE_SURFACE_MM - mid) < load_N else (low, mid)
    return high


def limit_for(obj: str, loads: Loads) -> float:
    """The plate: 10 N, met 0.17 mm into the gel (the force bound decides); the sphere: the simulated
    rig's own 40 N, which it does not reach above the floor (the depth bound decides)."""
    return PLATE_LIMIT_N if obj == "plate20mm" else SPHERE_LIMIT_N


class Watch:
    """The world's z every millisecond (its lowest; when it first touches the gel)."""

    def __init__(self, sim, on_touch, at_z: float = TRUE_SURFACE_MM):
        self.sim, self.on_touch, self.at_z = sim, on_touch, at_z
        self.lowest = sim.world.pose().z_mm
        self.touched = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        while not self._stop.is_set():
            z = self.sim.world.pose().z_mm
            self.lowest = min(self.lowest, z)
            if not self.touched and z < self.at_z:
                self.touched = True
                self.on_touch()
            self._stop.wait(0.001)

    def at_rest_for(self, seconds: float, limit_s: float) -> float:
        """Wait until the z stage has been at rest ``seconds``; returns how long it took."""
        t0 = time.monotonic()
        quiet_since = None
        stage = self.sim.world.stages["z"]
        while time.monotonic() - t0 < limit_s:
            if stage.busy(self.sim.clock.now()):
                quiet_since = None
            elif quiet_since is None:
                quiet_since = time.monotonic()
            elif time.monotonic() - quiet_since >= seconds:
                break
            time.sleep(0.02)
        return time.monotonic() - t0

    def close(self):
        self._stop.set()
        self._thread.join()


def run_case(case: Case, loads: Loads, workdir: Path, freeze_s: float) -> Outcome:
    from rig.config import load_config
    from rig.rig_state import RigState
    from rig.sim.rig_sim import SERVED_DEVICE_TIMEOUT_S, SimulatedRig
    from rig.sim.world import WorldSpec

    limit = limit_for(case.obj, loads)
    spec = WorldSpec()
    spec.start["z"] = spec.geometry["z"].origin - (TRUE_SURFACE_MM + START_ABOVE_MM)
    env = dict(os.environ, TACTILE_STATE_DIR=str(workdir / "state"), TACTILE_RUNTIME_DIR=str(workdir / "run"))
    (workdir / "run").mkdir(mode=0o700, exist_ok=True)
    with SimulatedRig(transport="pty", gauge="ft300", gauge_rate_hz=case.gauge_hz, indenter=case.obj, spec=spec) as sim:
        text = sim.config_toml(with_camera=False, device_timeout_s=SERVED_DEVICE_TIMEOUT_S)
        text = text.replace("max_force_N = [10.0, 10.0, 40.0]", f"max_force_N = [10.0, 10.0, {limit!r}]")
        cfg = workdir / f"rig-{case.obj}-{case.gauge_hz:g}.toml"
        cfg.write_text(text)
        device = sim.zaber.devices[3]  # z
        own_limits = device.native_limits()
        status = subprocess.run([RIG, "status", "--config", str(cfg)], env=env, capture_output=True, text=True)
        if status.returncode != 0:
            raise SystemExit(f"rig status failed: {status.stderr.strip()}")
        os.environ["TACTILE_STATE_DIR"] = env["TACTILE_STATE_DIR"]
        state = RigState.for_config(load_config(cfg))
        state.remember_tare(list(spec.gauge_offset))
        state.surfaces.clear()
        remembered = SURFACES[case.surface]
        state.mounted = OTHER_INDENTER if case.surface == "other" else case.obj
        state.remember_surface(remembered, "find-contact")
        target = remembered - FRACTION * GEL_MM
        process: subprocess.Popen | None = None

        def fail_now():
            if process is not None:
                os.kill(process.pid, signal.SIGSTOP if case.failure == "freeze" else signal.SIGKILL)

        at_z = TRUE_SURFACE_MM
        if case.moment == "half":
            at_z -= depth_for(case.obj, 0.5 * limit, loads)
        watch = Watch(sim, fail_now, at_z)
        args = ["jog", "--axis", "z", "--to", f"{target:.4f}", "--speed", f"{case.speed:g}", "--config", str(cfg)]
        process = subprocess.Popen(
            [RIG, *args, "--object", case.obj], env=env, stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )
        frozen = 0.0
        try:
            deadline = time.monotonic() + 240
            while process.poll() is None and not watch.touched and time.monotonic() < deadline:
                time.sleep(0.01)
            if watch.touched and case.failure == "freeze":
                frozen = watch.at_rest_for(REST_S, freeze_s)
                os.kill(process.pid, signal.SIGCONT)
            elif watch.touched:
                watch.at_rest_for(REST_S, 60.0)
            out, err = process.communicate(timeout=240)
        except subprocess.TimeoutExpired:
            process.kill()
            out, err = process.communicate()
            err += "\n(timed out)"
        if case.failure == "kill":
            after = subprocess.run([RIG, "status", "--config", str(cfg)], env=env, capture_output=True, text=True)
            err += after.stderr
        watch.close()
        restored = device.native_limits() == own_limits
        lines = [line for line in err.splitlines() if line.strip() and not line.startswith("note:")]
        said = lines[-1] if lines else (out.strip().splitlines() or [""])[-1]
        lowest = watch.lowest
    return Outcome(
        case,
        limit,
        loads.fz(case.obj, lowest),
        (TRUE_SURFACE_MM - FRACTION * GEL_MM) - lowest,
        frozen,
        restored,
        watch.touched,
        said[:110],
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1 mm/s, 100 Hz, freeze and kill, every surface")
    parser.add_argument("--freeze-s", type=float, default=60.0, help="the longest a process stays frozen (s)")
    parser.add_argument("--out", type=Path, help="also write the table to this file")
    parser.add_argument("--at", default="touch", help="when the process fails: touch, half or both (comma-separated)")
    args = parser.parse_args()
    speeds, gauges = ((1.0,), (100.0,)) if args.quick else (SPEEDS, GAUGES_HZ)
    moments = [m for m in args.at.split(",") if m in MOMENTS]
    cases = [
        Case(failure, speed, obj, hz, surface, moment)
        for moment in moments
        for failure in FAILURES
        for obj in OBJECTS
        for hz in gauges
        for surface in SURFACES
        for speed in speeds
    ]
    loads = Loads()
    lines = [
        f"machine: {describe()}",
        f"{len(cases)} cases; the process fails as the indenter first touches the gel (touch) or once the true "
        "load is half the limit (half)",
    ]
    lines.append(
        f"{'at':5s} {'failure':7s} {'object':10s} {'gauge':>6s} {'surface':8s} {'mm/s':>5s} {'limit N':>8s} "
        f"{'peak N':>8s} {'peak/lim':>8s} {'below floor':>11s} {'frozen':>7s} {'limits':>8s}  what the command said"
    )
    print("\n".join(lines), flush=True)
    outcomes = []
    with tempfile.TemporaryDirectory(prefix="host-failure-") as tmp:
        for i, case in enumerate(cases):
            workdir = Path(tmp) / f"case{i}"
            workdir.mkdir()
            o = run_case(case, loads, workdir, args.freeze_s)
            outcomes.append(o)
            line = (
                f"{case.moment:5s} {case.failure:7s} {case.obj:10s} {case.gauge_hz:4.0f}Hz {case.surface:8s} "
                f"{case.speed:5g} {o.limit_N:8.3f} {o.peak_N:8.3f} {o.ratio:8.3f} {o.below_floor_mm:+9.3f}mm "
                f"{o.frozen_s:6.1f}s {'restored' if o.restored else 'LEFT':>8s}  "
                + ("" if o.touched else "(never got there) ")
                + o.said
            )
            lines.append(line)
            print(line, flush=True)
    worst = max(o.ratio for o in outcomes)
    deepest = max(o.below_floor_mm for o in outcomes)
    left = sum(not o.restored for o in outcomes)
    tail = [
        f"controller limits left narrowed after a case: {left} of {len(outcomes)}",
        f"worst peak/limit: {worst:.3f}  deepest below floor: {deepest:+.3f} mm",
    ]
    lines += tail
    print("\n".join(tail))
    if args.out:
        args.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
