"""How far past its force limit the guard lets a press go: true peak ÷ limit on the simulated rig.

    .venv/bin/python bench/overshoot_bench.py [--quick] [--realtime] [--baseline-tree DIR]

Each case is one `rig jog --axis z --to TARGET --speed V` as the command runs it (a motion
session on the simulated rig's real drivers over ptys), on discrete-event time so that every
gauge sample, poll and stop lands on schedule whatever the machine's load. The peak is the
simulator's own load at the deepest z the indenter reached (the contact solver at that pose,
not the guard's readings): force grows with depth on a vertical press, and a stopped stage
rests at its deepest point until the stop sequence lifts it.

The matrix: speeds 0.01, 0.1, 1, 5 mm/s (5 mm/s is the simulated z stage's max_speed, the
fastest the CLI accepts for this rig; 1000 mm/s, the CLI's own bound, is refused by it), the
gauge streaming at 10, 100 and 1000 Hz, a soft object (sphere10mm) and the stiffest (plate20mm, a
rigid plate over the whole pad), and three targets:

- ``gel``: just above the depth floor (95 % of its depth), with the Fz limit set to the load
  at 70 % of the allowed depth, so the guard must stop the press inside the gel;
- ``past``: 1 mm past the gel's thickness at the default 40 N limit, without the override
  (the depth guard refuses it, or stops it at the first contact when the surface is unknown);
- ``deep`` (sphere10mm: the plate's load passes 40 N long before the window): the same with
  ``--allow-deep``, started 0.1 mm above the window (the way there is
  the slow part, at the window's speed: started higher, one case takes an hour of simulated
  time at 10 Hz; the bench knows where the simulated gel is, the rig only what find-contact
  told it), so the indenter reaches the window behind the gel and the guard stops it there.

Each runs with the gel surface remembered (found by find-contact first, as docs/safety.md asks)
and, for ``gel`` and ``past``, unknown (a fresh rig: the first contact of the move finds it).
``--realtime`` adds cases on the real clock in-process, as `rig jog --sim` runs them
(gauge latency bound 80 ms: the simulator's physics), 1 and 5 mm/s.

``--baseline-tree DIR``: the time to press 1.3 mm at 0.01 mm/s (from 0.3 mm above the gel to
1.0 mm into it) on that tree (e.g. `git worktree add /tmp/base COMMIT`), beside this one's.
The last line is ``worst peak/limit: X``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import threading
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common.machine import describe  # noqa: E402

SPEEDS = (0.01, 0.1, 1.0, 5.0)
CLI_MAX_SPEED = 1000.0
GAUGES_HZ = (10.0, 100.0, 1000.0)  # 1 kHz: where the load rate's 50 ms window differs from six samples
OBJECTS = ("sphere10mm", "plate20mm")
START_ABOVE_MM = 0.3  # cases start this far above the gel surface
DEEP_START_ABOVE_WINDOW_MM = 0.1
DEFAULT_FZ_LIMIT_N = 40.0
# Objects whose load at the window is under the 40 N limit: a plate carries ~230 N at 2.9 mm into
# the gel, so it trips long before the window and a "deep" case of it would start over its limit.
DEEP_LIMITS_N = {"sphere10mm": DEFAULT_FZ_LIMIT_N, "plate20mm": 250.0}  # the plate: a limit it meets at the window
TRUE_SURFACE_MM = 0.0  # where the simulated gel's surface is in axis z (rig/sim/rig_sim.py's geometry)


@dataclasses.dataclass
class Case:
    obj: str
    gauge_hz: float
    speed: float
    target: str  # gel | past | deep
    surface_known: bool
    realtime: bool = False


@dataclasses.dataclass
class Outcome:
    case: Case
    limit_N: float
    used_speed: float | None
    result: str
    peak_N: float
    sim_s: float
    lifted: bool  # after a stop: z off the gel, no load (the stop sequence's lift worked)

    @property
    def ratio(self) -> float:
        return self.peak_N / self.limit_N


def _deepest_tracker(sim, clock, realtime: bool):
    """The lowest world z (mm, negative = into the gel) the indenter reaches from now on."""
    state = {"z": sim.world.pose().z_mm, "stop": threading.Event()}

    def look():
        state["z"] = min(state["z"], sim.world.pose().z_mm)

    if realtime:

        def poll():
            while not state["stop"].wait(0.0005):
                look()

        thread = threading.Thread(target=poll, daemon=True)
        thread.start()
        return state, lambda: (state["stop"].set(), thread.join(), look())
    clock.add_listener(look)
    return state, look


_FOUND: dict[tuple[str, float], tuple[float, tuple[float, ...]]] = {}


def found_surface(obj: str, gauge_hz: float) -> tuple[float, tuple[float, ...]]:
    """(surface z, raw tare) as `rig find-contact` leaves them for this object and gauge on a
    fresh simulated rig: what a rig remembers between commands (rig/rig_state.py)."""
    from rig.clock import ManualClock
    from rig.contact_search import find_contact
    from rig.rig import Rig
    from rig.sim.rig_sim import SimulatedRig

    key = (obj, gauge_hz)
    if key not in _FOUND:
        clock = ManualClock()
        with SimulatedRig(clock, indenter=obj, gauge_rate_hz=gauge_hz, gauge_at_every_step=False) as sim:
            with Rig.open(sim.config(with_camera=False), clock, axes=("z",)) as rig:
                find_contact(rig, speed_mm_s=0.5, max_travel_mm=8.0)
                _FOUND[key] = (rig.state.surface.z_mm, rig.state.tare.raw_N)
    return _FOUND[key]


def run_case(case: Case) -> Outcome:
    """One jog, on a fresh simulated rig whose indenter starts where the case starts (a rig
    that was moved there before; its remembered surface and tare copied in when known)."""
    from objects.pose import Pose
    from rig.clock import ManualClock, SystemClock
    from rig.config import DEFAULT_MAX_DEPTH_FRACTION
    from rig.errors import RigError
    from rig.rig import Rig
    from rig.sim.rig_sim import SimulatedRig
    from rig.sim.world import WorldSpec
    from sensor_sim.elastomer import Elastomer

    known = found_surface(case.obj, case.gauge_hz) if case.surface_known else None
    surface = known[0] if known else TRUE_SURFACE_MM  # targets as a user types them: from find-contact's z
    spec = WorldSpec()
    clock = SystemClock() if case.realtime else ManualClock()
    thickness = Elastomer().thickness_mm  # the simulated rig's gel (its config states it as gel_thickness_mm)
    floor_depth = DEFAULT_MAX_DEPTH_FRACTION * thickness
    if case.target == "deep":
        start, target = TRUE_SURFACE_MM - thickness + DEEP_START_ABOVE_WINDOW_MM, surface - thickness - 1.0
    else:
        start = TRUE_SURFACE_MM + START_ABOVE_MM
        target = surface - 0.95 * floor_depth if case.target == "gel" else surface - thickness - 1.0
    spec.start["z"] = spec.geometry["z"].origin - start  # axis z = origin - stage position
    with SimulatedRig(
        clock, indenter=case.obj, gauge_rate_hz=case.gauge_hz, spec=spec, gauge_at_every_step=False
    ) as sim:
        cfg = sim.config(with_camera=False)
        assert cfg.safety.gel_thickness_mm == thickness and cfg.safety.max_depth_fraction == DEFAULT_MAX_DEPTH_FRACTION
        contact = sim.world.contact
        if case.target == "gel":
            limit = float(contact.wrench(Pose(0.0, 0.0, -0.7 * floor_depth, 0.0))[2])
            contact.reset()
        elif case.target == "deep":
            limit = DEEP_LIMITS_N[case.obj]
        else:
            limit = DEFAULT_FZ_LIMIT_N
        force = (cfg.safety.max_force_N[0], cfg.safety.max_force_N[1], limit)
        cfg = dataclasses.replace(cfg, safety=dataclasses.replace(cfg.safety, max_force_N=force))
        with Rig.open(cfg, clock, axes=("z",)) as rig:
            if known is not None:
                rig.state.remember_tare(known[1])
                rig.state.remember_surface(known[0], "find-contact")
            used: list[str] = []
            t0 = clock.now()
            deepest, finish = _deepest_tracker(sim, clock, case.realtime)
            result = "reached"
            try:
                with rig.motion(
                    "jog", allow_deep=case.target == "deep", on_start=used.append, on_note=lambda text: None
                ) as m:
                    m.jog("z", to=target, speed=case.speed)
            except RigError as exc:
                result = type(exc).__name__
            finally:
                if case.realtime:
                    finish()
                else:
                    clock.remove_listener(finish)
            elapsed = clock.now() - t0
            lifted = sim.world.pose().z_mm > TRUE_SURFACE_MM and sim.world.true_wrench()[2] == 0.0
            if not lifted and result == "reached":
                lifted = True  # a jog that reached its target stays there: nothing to lift
        contact.reset()
        peak = float(contact.wrench(Pose(0.0, 0.0, deepest["z"], 0.0))[2])
    return Outcome(case, limit, _first_speed(used), result, peak, elapsed, lifted)


def _first_speed(started: list[str]) -> float | None:
    """The speed of the jog's last segment, from the session's 'z: moving to … at V mm/s' lines."""
    speeds = [float(text.rsplit(" at ", 1)[1].split()[0]) for text in started if " at " in text]
    return speeds[-1] if speeds else None


def cases(quick: bool, realtime: bool) -> list[Case]:
    out = []
    speeds = (0.1, 5.0) if quick else SPEEDS
    for obj in OBJECTS:
        for hz in GAUGES_HZ:
            for speed in speeds:
                for target in ("gel", "past", "deep") if obj in DEEP_LIMITS_N else ("gel", "past"):
                    for known in (True, False) if target != "deep" else (True,):
                        if target == "deep" and speed not in (0.01, 5.0) and not quick:
                            continue  # the window's cap makes every speed the same case: the slowest and fastest
                        out.append(Case(obj, hz, speed, target, known))
    if realtime:
        for obj in OBJECTS:
            for speed in (1.0, 5.0):
                for target in ("gel", "past"):
                    out.append(Case(obj, 100.0, speed, target, True, realtime=True))
    return out


def envelope_table() -> list[str]:
    """The envelope as the simulated rig measures it (discrete time at 10 and 100 Hz, and real
    time as `rig jog --sim` runs): timing, and the in-contact z speed for a 40 N limit at a few
    stiffnesses (the configured default is 100 N/mm), and below the floor."""
    from rig.clock import ManualClock, SystemClock
    from rig.rig import Rig
    from rig.sim.rig_sim import SimulatedRig

    lines = [
        "envelope (Fz limit 40 N, overshoot allowed 10 %, checks every 20 ms): z speed in contact at a stiffness of",
        f"  {'rig':22s} {'gauge period':>12s} {'latency':>8s} {'stop':>7s} {'10 N/mm':>9s} {'100 N/mm':>9s} "
        f"{'1000 N/mm':>10s} {'window':>9s}",
    ]
    for name, clock, hz in (
        ("sim, 10 Hz gauge", ManualClock(), 10.0),
        ("sim, 100 Hz gauge", ManualClock(), 100.0),
        ("real time, 100 Hz", SystemClock(), 100.0),
    ):
        with SimulatedRig(clock, gauge_rate_hz=hz, gauge_at_every_step=False) as sim:
            with Rig.open(sim.config(with_camera=False), clock, axes=("z",)) as rig:
                env = rig.envelope()
                t = env.timing
                speeds = []
                for k in (10.0, 100.0, 1000.0):
                    env.measured_stiffness = None
                    env.safety = dataclasses.replace(env.safety, stiffness_N_per_mm=k)
                    speeds.append(env.cap("z", "gel", rig.config.safety.poll_s).speed)
                deep = env.cap("z", "deep", rig.config.safety.poll_s).speed
        lines.append(
            f"  {name:22s} {1000 * t.gauge_period_s:9.1f} ms {1000 * t.gauge_latency_s:5.0f} ms "
            f"{1000 * t.stop_latency_s('z'):4.1f} ms {speeds[0]:7.3g}   {speeds[1]:7.3g}   {speeds[2]:8.3g}   "
            f"{deep:7.2g}  mm/s"
        )
    return lines


def cli_max_speed_refused() -> str:
    """The CLI's own speed bound against the simulated rig: refused before anything moves."""
    from typer.testing import CliRunner

    from cli.rig_app import app

    result = CliRunner().invoke(app, ["jog", "--axis", "z", "--step", "-0.1", "--speed", str(CLI_MAX_SPEED), "--sim"])
    return result.output.strip().splitlines()[-1] if result.output.strip() else f"exit {result.exit_code}"


# Runs on this tree and on an older one (only calls both have): the 0.01 mm/s press time, and
# fast jogs toward -4 mm at the default 40 N limit as the issue found them (the window behind
# the gel, or the plate's stiff gel). An older tree's simulator stops its stages at once and
# reports a gauge sample at every clock step, both in its favour.
BASELINE_SCRIPT = """
import json, sys
from objects.pose import Pose
from rig.clock import ManualClock
from rig.rig import Rig
from rig.sim.rig_sim import SimulatedRig
from rig.sim.world import WorldSpec

def press_time():
    clock = ManualClock()
    with SimulatedRig(clock) as sim, Rig.open(sim.config(with_camera=False), clock, axes=("z",)) as rig:
        with rig.motion("setup") as m:
            m.move({"z": 0.3}, 0.5)
        t0 = clock.now()
        with rig.motion("press") as m:
            m.move({"z": -1.0}, 0.01)
        return clock.now() - t0

def jog(obj, speed):
    spec = WorldSpec()
    spec.start["z"] = spec.geometry["z"].origin - 0.3
    clock = ManualClock()
    with SimulatedRig(clock, indenter=obj, spec=spec) as sim:
        with Rig.open(sim.config(with_camera=False), clock, axes=("z",)) as rig:
            deepest = [sim.world.pose().z_mm]
            look = lambda: deepest.__setitem__(0, min(deepest[0], sim.world.pose().z_mm))
            clock.add_listener(look)
            try:
                with rig.motion("jog") as m:
                    m.jog("z", to=-4.0, speed=speed)
                outcome = "reached"
            except Exception as exc:
                outcome = type(exc).__name__
            clock._listeners.remove(look)
        sim.world.contact.reset()
        peak = float(sim.world.contact.wrench(Pose(0.0, 0.0, deepest[0], 0.0))[2])
    return {"object": obj, "speed": speed, "peak_N": peak, "outcome": outcome}

print(json.dumps({"press_s": press_time(), "jogs": [jog(o, v) for o in ("sphere10mm", "plate20mm") for v in (1.0, 5.0)
                                                     if o != "plate20mm" or "plate20mm" in sys.argv]}))
"""


def baseline(tree: Path, with_plate: bool) -> dict:
    """The baseline script's result on ``tree`` (a checkout, e.g. `git archive COMMIT | tar -x`)."""
    out = subprocess.run(
        [sys.executable, "-c", BASELINE_SCRIPT, *(["plate20mm"] if with_plate else [])],
        cwd=tree,
        capture_output=True,
        text=True,
        check=True,
        timeout=3600,
        env={"PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin", "TACTILE_STATE_DIR": "/tmp/overshoot-bench-state"},
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="speeds 0.1 and 5 mm/s only")
    parser.add_argument("--realtime", action="store_true", help="add real-clock cases (as `rig jog --sim`)")
    parser.add_argument("--baseline-tree", type=Path, help="a checkout to time the 0.01 mm/s press on")
    args = parser.parse_args()
    print(f"machine: {describe()}")
    print(
        f"{'object':11s} {'gauge':>6s} {'speed':>7s} {'used':>9s} {'target':6s} {'surface':8s} {'clock':5s} "
        f"{'limit N':>8s} {'peak N':>8s} {'peak/lim':>8s} {'sim s':>8s}  outcome"
    )
    worst = 0.0
    not_lifted = 0
    for case in cases(args.quick, args.realtime):
        o = run_case(case)
        worst = max(worst, o.ratio)
        not_lifted += not o.lifted
        used = f"{o.used_speed:.3g}" if o.used_speed is not None else "-"
        print(
            f"{case.obj:11s} {case.gauge_hz:5.0f}Hz {case.speed:7.2f} {used:>9s} {case.target:6s} "
            f"{'known' if case.surface_known else 'unknown':8s} {'real' if case.realtime else 'sim':5s} "
            f"{o.limit_N:8.2f} {o.peak_N:8.2f} {o.ratio:8.3f} {o.sim_s:8.1f}  {o.result}"
            + ("" if o.lifted else "  NOT LIFTED"),
            flush=True,
        )
    print(f"{CLI_MAX_SPEED:g} mm/s (the CLI's bound): {cli_max_speed_refused()}")
    for line in envelope_table():
        print(line)
    trees = [("this tree", ROOT, True)]
    if args.baseline_tree is not None:  # the older tree may not have the plate
        indenters = (args.baseline_tree / "objects" / "indenters.py").read_text()
        trees.append((str(args.baseline_tree), args.baseline_tree, "def plate(" in indenters))
    results = {name: baseline(tree, plate) for name, tree, plate in trees}
    print("fast jogs to z = -4 mm from 0.3 mm above the gel, Fz limit 40 N (the issue's case):")
    for name, result in results.items():
        for j in result["jogs"]:
            print(
                f"  {name:24s} {j['object']:11s} {j['speed']:4.1f} mm/s: peak {j['peak_N']:7.2f} N = "
                f"{j['peak_N'] / DEFAULT_FZ_LIMIT_N:5.2f} x limit ({j['outcome']})"
            )
    here = results["this tree"]["press_s"]
    line = f"press 1.3 mm at 0.01 mm/s: {here:.1f} s simulated on this tree"
    if args.baseline_tree is not None:
        base = results[str(args.baseline_tree)]["press_s"]
        line += f", {base:.1f} s on {args.baseline_tree} ({here / base:.2f}x)"
    print(line)
    print(f"cases where z was left in the gel after a stop: {not_lifted}")
    print(f"worst peak/limit: {worst:.3f}")


if __name__ == "__main__":
    main()
