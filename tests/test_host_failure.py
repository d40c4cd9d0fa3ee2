"""Motion safety that holds when the host stops answering and what it remembers is wrong
(docs/safety.md: the floor in the controller, bounded commands, a surface that belongs to its
indenter). Success is judged by the simulator: the true load at the deepest z reached, and that
z against the true depth floor."""

from __future__ import annotations

import dataclasses
import math

import pytest

from objects.pose import Pose
from rig.clock import ManualClock
from rig.drivers import zaber_ascii as za
from rig.errors import DepthLimitError, ForceLimitExceeded, SafetyError
from rig.rig import Rig
from rig.sim.rig_sim import SimulatedRig
from rig.sim.stage import SimStage, StageSpec
from rig.sim.world import WorldSpec
from rig.sim.zaber_sim import ZaberChainSim, ZaberDeviceSim

TRUE_SURFACE = 0.0
GEL_MM = 3.0
TRUE_FLOOR = TRUE_SURFACE - 0.6 * GEL_MM


# -- the Zaber simulator's travel limits, byte for byte ---------------------------------------
def _chain():
    clock = ManualClock()
    stage = SimStage("z", StageSpec(travel=(0.0, 25.0), max_speed=5.0, accel=20.0), position=5.0)
    dev = ZaberDeviceSim(stage, 0.047625e-3)
    return clock, stage, dev, ZaberChainSim(clock, {1: dev})


def _ask(sim, clock, text: str) -> str:
    (reply,) = sim.feed(za.format_command(1, 1, text, 7), clock.now())
    return reply.decode().strip()


def test_zaber_limits_are_set_read_back_and_enforced_on_every_move_command():
    clock, stage, dev, sim = _chain()
    assert _ask(sim, clock, "get limit.max") == "@01 1 07 OK IDLE -- 524934"  # the stage's 25 mm
    assert _ask(sim, clock, "set limit.max 146982") == "@01 1 07 OK IDLE -- 0"  # 7 mm
    assert _ask(sim, clock, "get limit.max") == "@01 1 07 OK IDLE -- 146982"
    # a move abs or rel beyond it is rejected BADDATA and nothing moves
    assert _ask(sim, clock, "move abs 200000") == "@01 1 07 RJ IDLE -- BADDATA"
    assert _ask(sim, clock, "move rel 100000") == "@01 1 07 RJ IDLE -- BADDATA"
    assert stage.position(clock.now()) == 5.0
    # a velocity move, and `move max`, stop at it
    assert _ask(sim, clock, "move vel 100000").startswith("@01 1 07 OK BUSY")
    clock.advance(30.0)
    assert stage.position(clock.now()) == pytest.approx(146982 * 0.047625e-3, abs=1e-6)
    assert _ask(sim, clock, "move vel 100000") == "@01 1 07 RJ IDLE -- BADDATA"  # at the limit: no further
    # a limit that leaves the carriage outside is accepted; it may then only come back into the range
    assert _ask(sim, clock, "set limit.max 41995") == "@01 1 07 OK IDLE -- 0"  # 2 mm, below where it is
    assert _ask(sim, clock, "move abs 146000") == "@01 1 07 RJ IDLE -- BADDATA"
    assert _ask(sim, clock, "move abs 41995").startswith("@01 1 07 OK BUSY")
    # a move under way is cut short at a new limit (ASSUMED, rig/sim/zaber_sim.py)
    clock.advance(10.0)
    assert _ask(sim, clock, "set limit.max 524934") == "@01 1 07 OK IDLE -- 0"
    assert _ask(sim, clock, "move abs 400000").startswith("@01 1 07 OK BUSY")
    assert _ask(sim, clock, "set limit.max 100000") == "@01 1 07 OK BUSY -- 0"
    clock.advance(30.0)
    assert stage.position(clock.now()) == pytest.approx(100000 * 0.047625e-3, abs=1e-6)


def test_the_power_up_token_is_volatile_and_device_scope():
    clock, stage, dev, sim = _chain()
    (reply,) = sim.feed(za.format_command(1, 0, "set user.vdata.0 123456789", 3), clock.now())
    assert reply.decode().startswith("@01 0 03 OK")
    assert _ask(sim, clock, "get user.vdata.0").endswith("DEVICEONLY")  # axis 1 may not ask a device setting
    (reply,) = sim.feed(za.format_command(1, 0, "get user.vdata.0", 4), clock.now())
    assert reply.decode().strip().endswith(" 123456789")
    dev.power_cycle()
    (reply,) = sim.feed(za.format_command(1, 0, "get user.vdata.0", 5), clock.now())
    assert reply.decode().strip().endswith(" 0")


# -- the simulated rig: presses whose host stops answering ----------------------------------------
def open_sim(obj: str, start_z: float, *, fz_limit: float | None = None, gauge_hz: float = 100.0):
    spec = WorldSpec()
    spec.start["z"] = spec.geometry["z"].origin - start_z
    clock = ManualClock()
    sim = SimulatedRig(clock, indenter=obj, gauge_rate_hz=gauge_hz, spec=spec, gauge_at_every_step=False)
    cfg = sim.config(with_camera=False)
    if fz_limit is not None:
        limits = (cfg.safety.max_force_N[0], cfg.safety.max_force_N[1], fz_limit)
        cfg = dataclasses.replace(cfg, safety=dataclasses.replace(cfg.safety, max_force_N=limits))
    return sim, Rig.open(cfg, clock, axes=("z",))


def load_at(sim, z_mm: float) -> float:
    contact = sim.world.contact
    contact.reset()
    return float(contact.wrench(Pose(0.0, 0.0, min(z_mm, 0.0), 0.0))[2])


def freeze_after_start(sim, rig, target: float, speed: float, *, touch_first: bool):
    """A descent started as a session starts one, then the host freezes: nothing checks, nothing is
    sent, for 120 s of simulated time. ``touch_first``: the session's checks run until the indenter
    first touches the gel, as a host that froze just then. Returns the lowest z reached."""
    lowest = [sim.world.pose().z_mm]

    def look():
        lowest[0] = min(lowest[0], sim.world.pose().z_mm)

    sim.clock.add_listener(look)
    frozen = False
    with pytest.raises(_Frozen), rig.motion("jog", on_note=lambda text: None) as m:
        guard = m.start_move({"z": target}, speed)
        while touch_first and sim.world.pose().z_mm > TRUE_SURFACE:
            if not m.monitor(("z",), guard):
                break
            rig.clock.sleep(rig.config.safety.poll_s)
        frozen = True
        end = sim.clock.now() + 120.0
        while sim.clock.now() < end:  # the host is gone: only the simulated world goes on
            sim.clock.advance(0.01)
        raise _Frozen
    assert frozen
    sim.clock.remove_listener(look)
    return lowest[0]


class _Frozen(Exception):
    """Ends the frozen host's session (its stop sequence then runs, as after a SIGCONT)."""


@pytest.mark.parametrize("obj, limit", [("sphere10mm", 4.45), ("plate20mm", 10.0)])
@pytest.mark.parametrize("remembered", [0.0, -0.5, -1.0, None])
@pytest.mark.parametrize("touch_first", [False, True])
def test_a_frozen_host_leaves_the_press_within_its_limit_and_above_the_floor(obj, limit, remembered, touch_first):
    sim, rig = open_sim(obj, TRUE_SURFACE + 2.0, fz_limit=limit)
    with sim, rig:
        rig.state.remember_tare([0.12, -0.08, 0.35, 4.0, -3.0, 1.5])  # the simulated gauge's offsets
        if remembered is not None:
            rig.state.remember_surface(remembered, "find-contact")
        target = (remembered if remembered is not None else -1.0) - 0.6 * GEL_MM
        lowest = freeze_after_start(sim, rig, target, 5.0, touch_first=touch_first)
        assert load_at(sim, lowest) <= 1.10 * limit, f"z {lowest:.3f}: {load_at(sim, lowest):.2f} N"
        assert lowest >= TRUE_FLOOR - 1e-3, f"z {lowest:.3f} below the true floor {TRUE_FLOOR}"
    # the stop sequence restored the controller's own limits
    assert sim.zaber.devices[3].limit_max in (None, 524934) and rig.state.device_limits == {}


def test_the_controller_holds_the_floor_during_a_descent_and_gets_its_own_limits_back():
    sim, rig = open_sim("sphere10mm", TRUE_SURFACE + 0.5)
    with sim, rig:
        rig.state.remember_surface(TRUE_SURFACE, "find-contact")
        z_dev = sim.zaber.devices[3]
        own = z_dev.native_limits()
        seen = []
        sim.clock.add_listener(lambda: seen.append(z_dev.native_limits()))
        with rig.motion("jog") as m:
            m.jog("z", to=-1.0, speed=0.3)
        narrowed = {limits for limits in seen if limits != own}
        floor_native = rig.axes["z"].native_range(TRUE_FLOOR, TRUE_FLOOR)[1]  # z down is + microsteps here
        assert narrowed == {(own[0], floor_native)}
        assert z_dev.native_limits() == own and rig.state.device_limits == {}


def _file_rig(sim, tmp_path, clock):
    """The simulated rig opened from a config file: its state is a file, as on hardware."""
    from rig.config import load_config

    path = tmp_path / "rig.toml"
    path.write_text(sim.config_toml(with_camera=False))
    return Rig.open(load_config(path), clock, axes=("z",))


def test_a_limit_a_killed_process_left_behind_is_restored_by_the_next_command(tmp_path, caplog):
    spec = WorldSpec()
    clock = ManualClock()
    with SimulatedRig(clock, spec=spec) as sim:
        z_dev = sim.zaber.devices[3]
        own = z_dev.native_limits()
        rig = _file_rig(sim, tmp_path, clock)
        rig.state.remember_surface(TRUE_SURFACE, "find-contact")
        from rig.device_floor import ControllerFloor

        ControllerFloor(rig).hold(TRUE_FLOOR)  # a session narrowed them; then its process was killed
        assert z_dev.native_limits() != own and "z" in rig.state.device_limits
        rig.close()
        with caplog.at_level("WARNING"):
            again = _file_rig(sim, tmp_path, clock)  # the next command opens z
        again.close()
        assert z_dev.native_limits() == own and again.state.device_limits == {}
        assert any("are restored" in r.getMessage() for r in caplog.records)


def test_the_half_millimetre_blind_spot_stops_at_first_contact():
    """The issue's case: the surface remembered 0.5 mm too low, `rig jog --axis z --to FLOOR --speed
    5` went to 78 % of the gel. The first contact, seen in any phase of the move, moves the floor up
    and stops the jog there."""
    sim, rig = open_sim("sphere10mm", TRUE_SURFACE + 2.0)
    with sim, rig:
        rig.state.remember_tare([0.12, -0.08, 0.35, 4.0, -3.0, 1.5])
        rig.state.remember_surface(TRUE_SURFACE - 0.5, "find-contact")
        lowest = [0.0]
        sim.clock.add_listener(lambda: lowest.__setitem__(0, min(lowest[0], sim.world.pose().z_mm)))
        notes = []
        with pytest.raises(DepthLimitError, match="depth guard"), rig.motion("jog", on_note=notes.append) as m:
            m.jog("z", to=TRUE_SURFACE - 0.5 - 1.8, speed=5.0)
        assert any("first contact" in n for n in notes), notes
        assert lowest[0] > TRUE_SURFACE - 0.3, lowest[0]  # stopped within a few tenths of the touch
        assert rig.state.surface.z_mm > TRUE_SURFACE - 0.3  # the surface moved up to where it is


def test_the_fast_approach_ends_above_the_surfaces_uncertainty():
    """Full speed only above the remembered surface + surface_uncertainty_mm + the clearance: with
    the surface 1 mm too low, a rigid plate is met at the in-contact speed, not at 5 mm/s."""
    sim, rig = open_sim("plate20mm", TRUE_SURFACE + 3.0, fz_limit=10.0)
    with sim, rig:
        rig.state.remember_tare([0.12, -0.08, 0.35, 4.0, -3.0, 1.5])
        rig.state.remember_surface(TRUE_SURFACE - 1.0, "find-contact")
        speeds = []
        sim.clock.add_listener(
            lambda: speeds.append((sim.world.pose().z_mm, sim.world.stages["z"].velocity(sim.clock.now())))
        )
        lowest = [0.0]
        sim.clock.add_listener(lambda: lowest.__setitem__(0, min(lowest[0], sim.world.pose().z_mm)))
        with pytest.raises((ForceLimitExceeded, DepthLimitError)), rig.motion("jog", on_note=lambda t: None) as m:
            m.jog("z", to=TRUE_SURFACE - 1.0 - 1.8, speed=5.0)
        # the stage's + is world -z: a positive velocity is the descent (the lift after the stop is not)
        at_touch = [v for z, v in speeds if TRUE_SURFACE - 0.05 < z < TRUE_SURFACE + 0.05 and v > 0]
        assert at_touch and max(at_touch) < 0.5, max(at_touch)
        assert load_at(sim, lowest[0]) <= 1.10 * 10.0


# -- whose surface --------------------------------------------------------------------------------
def test_a_surface_belongs_to_its_indenter_homing_power_up_and_age(tmp_path):
    sim, rig = open_sim("sphere10mm", TRUE_SURFACE + 1.0)
    with sim, rig:
        state = rig.state
        state.mount("sphere10mm")
        state.remember_surface(-0.2, "find-contact")
        assert rig.depth_guard() is not None
        assert "mounted" in state.mount("plate20mm")
        assert rig.depth_guard() is None and "none measured with plate20mm" in state.why_unknown(
            state.surfaces.get("plate20mm")
        )
        state.mount("sphere10mm")
        assert rig.depth_guard().surface_z == -0.2  # the sphere's surface is remembered beside it
        state.note_z_homed()
        assert rig.depth_guard() is None and "homed" in state.why_unknown(state.surfaces["sphere10mm"])
        state.remember_surface(-0.2, "find-contact")
        state.max_age_s = 10.0
        assert "more than" in state.why_unknown(
            state.surfaces["sphere10mm"], now_unix=state.surfaces["sphere10mm"].t_unix + 11
        )
        state.max_age_s = math.inf


def test_a_power_cycle_of_the_z_controller_makes_the_surface_unknown(tmp_path, caplog):
    clock = ManualClock()
    with SimulatedRig(clock) as sim:
        rig = _file_rig(sim, tmp_path, clock)
        rig.state.remember_surface(-0.2, "find-contact")
        rig.close()
        again = _file_rig(sim, tmp_path, clock)  # the same power-up: the surface stands
        assert again.depth_guard() is not None
        again.close()
        sim.zaber.devices[3].power_cycle()  # off and on: its volatile token is gone
        with caplog.at_level("WARNING"):
            after = _file_rig(sim, tmp_path, clock)
        after.close()
        assert after.depth_guard() is None
        assert "powered off" in after.state.why_unknown(after.state.surfaces[""])
        assert any("powered off and on" in r.getMessage() for r in caplog.records)


def test_a_controller_that_cannot_hold_a_limit_refuses_descents(monkeypatch):
    from rig.drivers.zaber import ZaberAxis

    sim, rig = open_sim("sphere10mm", TRUE_SURFACE + 1.0)
    with sim, rig:
        monkeypatch.delattr(ZaberAxis, "native_limits")
        with pytest.raises(SafetyError, match="cannot hold a travel limit"), rig.motion("jog") as m:
            m.jog("z", to=0.5, speed=0.5)
        assert sim.world.pose().z_mm == pytest.approx(TRUE_SURFACE + 1.0, abs=1e-6)  # nothing moved


def test_the_speed_note_says_the_surface_is_unknown_not_that_the_gel_is_touched():
    sim, rig = open_sim("sphere10mm", TRUE_SURFACE + 0.4)
    with sim, rig:
        notes = []
        with rig.motion("jog", on_note=notes.append) as m:
            m.jog("z", to=TRUE_SURFACE + 0.2, speed=5.0)
        (clamp,) = [n for n in notes if "clamped to" in n]
        assert "near the gel (its surface is not known)" in clamp and "in contact with" not in clamp


class _Buffer:
    def __init__(self, stamps):
        from rig.types import Wrench

        self.samples = [Wrench.from_array(t, [0.0] * 6) for t in stamps]

    def newest(self, n):
        return self.samples[-n:]


class _Gauge:
    """A streaming gauge whose arrivals were bunched by a stalled host: 100 Hz, with three gaps of
    0.3 s among the newest 40, two of them among the newest 6 (the 90th percentile of those, the
    old measure, read 0.3 s)."""

    streaming = True
    fresh_after_s = 0.0

    def __init__(self, clock):
        stamps, t = [], 0.0
        for i in range(60):
            t += 0.3 if i in (35, 54, 57) else 0.01
            stamps.append(t)
        self.buffer = _Buffer(stamps)
        self.clock = clock

    def read_fresh(self):
        t = self.buffer.samples[-1].t_s + 0.01
        self.buffer.samples.append(type(self.buffer.samples[0]).from_array(t, [0.0] * 6))
        return self.buffer.samples[-1]

    def read(self):
        return self.buffer.samples[-1]


def test_the_gauge_period_is_the_median_gap_and_a_stall_does_not_move_it():
    from types import SimpleNamespace

    from rig.envelope import measure_timing

    clock = ManualClock()
    rig = SimpleNamespace(clock=clock, gauge=_Gauge(clock), axes={}, config=SimpleNamespace(axes={}))
    timing = measure_timing(rig)
    assert timing.gauge_period_s == pytest.approx(0.01)  # the median: the stalls do not count
    assert timing.gauge_gap_s >= 0.01  # the worst gaps still decide when the gauge has gone quiet
