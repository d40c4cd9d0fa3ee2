"""The depth guard and the speed envelope (rig/envelope.py, docs/safety.md): no press passes
its force limit by more than the allowed 10 %, at any speed the rig accepts, on soft and stiff
contacts and with the gauge at 10 or 100 Hz; nothing goes below the depth floor unless asked.

The true peak is the simulator's own load at the deepest z the indenter reached, never the
guard's readings (those are what is being tested)."""

from __future__ import annotations

import dataclasses
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from objects.pose import Pose
from rig.clock import ManualClock
from rig.contact_search import find_contact
from rig.envelope import overshoot, predict, safe_speed
from rig.errors import DepthLimitError, ForceLimitExceeded, RigError
from rig.rig import Rig
from rig.sim.rig_sim import SimulatedRig
from rig.sim.world import WorldSpec

TRUE_SURFACE = 0.0  # the simulated gel's surface in axis z


# -- the arithmetic -------------------------------------------------------------------------
@given(
    k=st.floats(1.0, 1e5),
    allowance=st.floats(0.01, 30.0),
    reaction=st.floats(0.001, 2.0),
    decel=st.floats(1.0, 1e4),
)
def test_the_safe_speed_overshoots_by_exactly_the_allowance(k, allowance, reaction, decel):
    v = safe_speed(k, allowance, reaction, decel)
    assert v > 0
    assert overshoot(v, k, reaction, decel) == pytest.approx(allowance, rel=1e-6)
    assert safe_speed(2 * k, allowance, reaction, decel) < v  # stiffer: slower
    assert safe_speed(k, allowance, 2 * reaction, decel) < v  # slower to stop: slower


def test_the_predicted_load_trips_before_the_reading_does():
    limits = [10.0, 10.0, 40.0, 300.0, 300.0, 200.0]
    now = [0.0, 0.0, 38.0, 0.0, 0.0, 0.0]
    assert predict(now, [0.0, 0.0, 10.0, 0, 0, 0], 0.1, limits) is None  # 38 + 1 N: under
    ahead = predict(now, [0.0, 0.0, 30.0, 0, 0, 0], 0.1, limits)  # 38 + 3 N: over
    assert ahead is not None and ahead.component == "Fz" and ahead.value == pytest.approx(41.0)
    assert predict(now, [0.0, 0.0, -300.0, 0, 0, 0], 0.1, limits) is None  # unloading never trips
    assert predict([0, -9.5, 0, 0, 0, 0], [0, -10.0, 0, 0, 0, 0], 0.1, limits).component == "Fy"  # either sign


# -- the simulated rig ----------------------------------------------------------------------
def open_sim(obj: str, gauge_hz: float, start_z: float, *, fz_limit: float | None = None, **safety):
    """A simulated rig (discrete-event time) whose indenter starts at axis ``start_z``."""
    spec = WorldSpec()
    spec.start["z"] = spec.geometry["z"].origin - start_z
    clock = ManualClock()
    sim = SimulatedRig(clock, indenter=obj, gauge_rate_hz=gauge_hz, spec=spec, gauge_at_every_step=False)
    cfg = sim.config(with_camera=False)
    changes = dict(safety)
    if fz_limit is not None:
        changes["max_force_N"] = (cfg.safety.max_force_N[0], cfg.safety.max_force_N[1], fz_limit)
    cfg = dataclasses.replace(cfg, safety=dataclasses.replace(cfg.safety, **changes))
    return sim, Rig.open(cfg, clock, axes=("z",))


class Deepest:
    """The lowest axis z the indenter reaches while attached (after every clock step)."""

    def __init__(self, sim):
        self.sim, self.z = sim, sim.world.pose().z_mm
        sim.clock.add_listener(self.look)

    def look(self):
        self.z = min(self.z, self.sim.world.pose().z_mm)

    def peak_fz(self) -> float:
        self.sim.clock.remove_listener(self.look)
        contact = self.sim.world.contact
        contact.reset()
        return float(contact.wrench(Pose(0.0, 0.0, self.z, 0.0))[2])


def load_at(obj: str, depth_mm: float) -> float:
    sim = SimulatedRig(ManualClock(), indenter=obj)
    with sim:
        return float(sim.world.contact.wrench(Pose(0.0, 0.0, -depth_mm, 0.0))[2])


@pytest.mark.slow
@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    speed=st.floats(0.02, 5.0),
    obj=st.sampled_from(["sphere10mm", "circle8mm", "plate20mm"]),
    gauge_hz=st.sampled_from([10.0, 100.0]),
    depth_fraction=st.floats(0.3, 0.9),
)
def test_a_press_into_the_gel_stops_within_ten_percent_of_its_limit(speed, obj, gauge_hz, depth_fraction):
    # The limit is the load at some depth inside the allowed 1.8 mm: the guard must stop there.
    limit = load_at(obj, depth_fraction * 1.8)
    sim, rig = open_sim(obj, gauge_hz, TRUE_SURFACE + 0.3, fz_limit=limit)
    with sim, rig:
        deepest = Deepest(sim)
        with pytest.raises(ForceLimitExceeded), rig.motion("jog", on_note=lambda text: None) as m:
            m.jog("z", to=TRUE_SURFACE - 1.8, speed=speed)
        assert deepest.peak_fz() <= 1.10 * limit


@pytest.mark.slow
def test_a_fast_jog_into_the_window_is_stopped_by_the_depth_guard_not_the_force_limit():
    """The issue's case: `rig jog --axis z --to -4 --speed 1` drove a 10 mm sphere through the
    3 mm gel into the window (119-300 N against a 40 N limit)."""
    sim, rig = open_sim("sphere10mm", 100.0, TRUE_SURFACE + 0.3)
    notes = []
    with sim, rig:
        deepest = Deepest(sim)
        with pytest.raises(DepthLimitError, match="depth guard allows 1.80 mm"):
            with rig.motion("jog", on_note=notes.append) as m:
                m.jog("z", to=-4.0, speed=1.0)
        assert deepest.peak_fz() < 1.0  # stopped at the first contact, which found the surface
        assert any("clamped to" in note for note in notes)  # the surface was unknown: in-contact speed
        assert rig.state.surface is not None and -0.3 < rig.state.surface.z_mm < 0.0
        before = rig.axes["z"].position()
        with pytest.raises(DepthLimitError, match="nothing was moved"), rig.motion("jog") as m:
            m.jog("z", to=-4.0, speed=1.0)  # now known: refused before the first byte
        assert rig.axes["z"].position() == pytest.approx(before, abs=1e-6)


@pytest.mark.slow
def test_past_the_floor_only_when_asked_and_only_at_the_windows_speed():
    sim, rig = open_sim("sphere10mm", 100.0, TRUE_SURFACE - 2.9)  # 0.1 mm above the window
    with sim, rig:
        rig.state.remember_surface(TRUE_SURFACE - 0.1, "find-contact")
        rig.state.remember_tare([0.12, -0.08, 0.35, 4.0, -3.0, 1.5])  # the simulated gauge's offsets
        deepest = Deepest(sim)
        notes = []
        with pytest.raises(ForceLimitExceeded):
            with rig.motion("jog", allow_deep=True, on_note=notes.append) as m:
                m.jog("z", to=-4.0, speed=5.0)
        assert deepest.peak_fz() <= 1.10 * 40.0  # the window reached, the stop held
        assert deepest.z < -3.0  # it did reach the window
        (note,) = [n for n in notes if "clamped to" in n]
        assert "below the depth floor" in note and "the window behind the gel" in note
        cap = float(note.split("clamped to ")[1].split()[0])
        assert cap < 0.01  # a few µm/s: a window is tens of N per µm


def test_the_measured_timing_is_the_gauges_and_reported_by_status():
    for hz in (10.0, 100.0):
        sim, rig = open_sim("sphere10mm", hz, 1.0)
        with sim, rig:
            timing = rig.envelope().timing
            assert timing.gauge_period_s == pytest.approx(1.0 / hz, rel=0.25)
            assert timing.stop_latency_s("z") >= rig.config.axes["z"].stop_latency_s
            slow = rig.envelope().cap("z", "gel", rig.config.safety.poll_s).speed
        if hz == 10.0:
            slow_10 = slow
    assert slow > slow_10  # a faster gauge stops sooner: a faster press is safe


@pytest.mark.slow
def test_a_contact_stiffer_than_configured_slows_the_press():
    # configured for a soft contact (5 N/mm); the plate measures ~20× that
    sim, rig = open_sim("plate20mm", 100.0, TRUE_SURFACE + 0.05, fz_limit=60.0, stiffness_N_per_mm=5.0)
    notes = []
    with sim, rig:
        with pytest.raises(ForceLimitExceeded), rig.motion("jog", on_note=notes.append) as m:
            m.jog("z", to=-1.5, speed=5.0)
    assert any("measures stiffer than assumed" in n for n in notes), notes
    assert any(n.startswith("z: slowed from") for n in notes), notes


def test_a_protocol_deeper_than_the_floor_is_refused_before_anything_moves(tmp_path):
    from typer.testing import CliRunner

    from cli.rig_app import app

    result = CliRunner().invoke(
        app, ["run-protocol", "sphere10mm", "--sim", "--dry-run", "--set", "motion.max_depth_mm=2.4"]
    )
    assert result.exit_code == 1
    assert "goes to z = -2.400 mm" in result.output and "depth guard allows 1.80 mm" in result.output


def test_a_protocol_speed_outside_the_envelope_is_refused_not_slowed(tmp_path):
    from typer.testing import CliRunner

    from cli.rig_app import app

    out = tmp_path / "run.h5"
    result = CliRunner().invoke(
        app, ["run-protocol", "sphere10mm", "--sim", "--out", str(out), "--set", "motion.speed_mm_s=3.0"]
    )
    assert result.exit_code == 1 and "faster than the speed envelope" in result.output, result.output
    assert not out.exists()


def test_a_jog_faster_than_the_envelope_is_clamped_with_one_line(tmp_path):
    from typer.testing import CliRunner

    from cli.rig_app import app

    result = CliRunner().invoke(app, ["jog", "--axis", "z", "--step", "-0.2", "--speed", "5", "--sim"])
    assert result.exit_code == 0, result.output
    clamps = [line for line in result.output.splitlines() if "clamped to" in line]
    assert len(clamps) == 1 and clamps[0].startswith("note: z: 5 mm/s clamped to ")
    assert "configured worst case" in clamps[0] and "Fz limit 40 N" in clamps[0]
    assert "z = 4.8000 mm" in result.output


def test_the_envelope_refuses_what_no_speed_makes_safe():
    sim, rig = open_sim("sphere10mm", 10.0, 0.3, fz_limit=0.01)  # a 1 mN limit at 10 Hz
    with sim, rig:
        with pytest.raises(RigError, match="no speed is safe"), rig.motion("jog") as m:
            m.jog("z", to=-0.5, speed=0.01)


def test_the_sim_config_states_the_gel_and_a_real_config_must():
    from common.errors import ConfigError
    from rig.config import parse_config

    sim = SimulatedRig(ManualClock())
    with sim:
        text = sim.config_toml(with_camera=False)
    assert "gel_thickness_mm = 3.0" in text
    with pytest.raises(ConfigError, match=r"safety.gel_thickness_mm\] is required when a z axis is configured"):
        parse_config(text.replace("gel_thickness_mm = 3.0", ""), "rig.toml")
    assert math.isfinite(parse_config(text, "rig.toml").safety.stiffness_N_per_mm)


@pytest.mark.slow
def test_find_contact_remembers_the_surface_for_later_commands(tmp_path):
    sim, rig = open_sim("sphere10mm", 100.0, 1.0)
    with sim, rig:
        found = find_contact(rig, speed_mm_s=0.5, max_travel_mm=3.0)
        assert rig.state.surface.z_mm == found.z_mm and rig.state.surface.how == "find-contact"
        assert rig.depth_guard().floor_z == pytest.approx(found.z_mm - 1.8)


# -- regressions found in review ------------------------------------------------------------
def off_the_gel(sim) -> bool:
    return sim.world.pose().z_mm > TRUE_SURFACE and sim.world.true_wrench()[2] == 0.0


@pytest.mark.slow
def test_a_trip_at_speed_on_the_stiffest_contact_still_lifts_clear():
    """The stop brakes after the trip; the lift used to start while z still pressed on and give up
    at the limit ("retract failed"), leaving the plate in the gel at 70 N."""
    limit = load_at("plate20mm", 0.7 * 1.8)
    for _ in range(3):
        sim, rig = open_sim("plate20mm", 100.0, TRUE_SURFACE + 0.3, fz_limit=limit)
        reports = []
        with sim, rig:
            with pytest.raises(ForceLimitExceeded), rig.motion("jog", on_stop=reports.append) as m:
                m.jog("z", to=TRUE_SURFACE - 1.8, speed=5.0)
            assert reports[0].cleanup_errors == [], reports[0]
            assert off_the_gel(sim)


@pytest.mark.slow
def test_a_session_that_starts_pressed_with_nothing_remembered_learns_no_surface():
    """Its first reading is a pressed one: the next rise in load is not the gel's surface (the floor
    would lie past the window). It stops, says why, and remembers nothing."""
    from rig.contact_state import StartedPressed

    sim, rig = open_sim("sphere10mm", 100.0, TRUE_SURFACE - 1.5)
    with sim, rig:
        with pytest.raises(StartedPressed, match="may have started pressed"), rig.motion("jog") as m:
            m.jog("z", to=-3.3, speed=1.0)
        assert rig.state.surface is None
        assert sim.world.pose().z_mm > -1.6  # stopped within a few µm of where it started
        assert load_at("sphere10mm", -sim.world.pose().z_mm) < 40.0


@pytest.mark.slow
def test_a_first_contact_above_the_remembered_surface_always_moves_it_up():
    sim, rig = open_sim("sphere10mm", 100.0, TRUE_SURFACE + 0.3)
    with sim, rig:
        rig.tare(10)
        rig.state.remember_surface(TRUE_SURFACE - 0.24, "find-contact")  # out of date: 0.24 mm too low
        with pytest.raises(DepthLimitError), rig.motion("jog", on_note=lambda text: None) as m:
            m.jog("z", to=-2.0, speed=1.0)  # allowed against the old floor (-2.04), not the new one
        assert rig.state.surface.z_mm > -0.2 and rig.state.surface.how.startswith("first contact")
        assert off_the_gel(sim)


def test_a_floor_too_deep_for_the_gel_is_refused_by_the_config():
    from common.errors import ConfigError
    from rig.config import deepest_fraction, parse_config

    sim = SimulatedRig(ManualClock())
    with sim:
        text = sim.config_toml(with_camera=False)
    assert deepest_fraction(3.0) == pytest.approx(0.80)
    with pytest.raises(ConfigError, match=r"max_depth_fraction\] must be <= 0.80 for a 3 mm gel"):
        parse_config(text.replace("gel_thickness_mm = 3.0", "gel_thickness_mm = 3.0\nmax_depth_fraction = 0.95"))
    thin = parse_config(text.replace("gel_thickness_mm = 3.0", "gel_thickness_mm = 0.6"))
    assert thin.safety.max_depth_fraction == pytest.approx(deepest_fraction(0.6), abs=1e-3)  # the default, bounded
    assert thin.safety.max_depth_fraction < 0.6


@pytest.mark.slow
def test_find_contact_works_again_once_a_surface_is_remembered():
    sim, rig = open_sim("sphere10mm", 100.0, 1.0)
    with sim, rig:
        first = find_contact(rig, speed_mm_s=0.5, max_travel_mm=3.0)
        second = find_contact(rig, speed_mm_s=0.5, max_travel_mm=3.0)
    assert second.z_mm == pytest.approx(first.z_mm, abs=0.01)


@pytest.mark.slow
def test_a_gauge_gone_quiet_mid_press_stops_the_press():
    sim, rig = open_sim("plate20mm", 100.0, TRUE_SURFACE + 0.3, fz_limit=60.0)
    with sim, rig:
        rig.tare(10)

        def go_quiet():
            if sim.world.true_wrench()[2] > 20.0:
                sim.clock.remove_listener(go_quiet)
                sim.servers["gauge"].faults.drop_next(40)  # 0.4 s of samples lost

        sim.clock.add_listener(go_quiet)
        deepest = Deepest(sim)
        with pytest.raises((RigError, ForceLimitExceeded)), rig.motion("jog", on_note=lambda text: None) as m:
            m.jog("z", to=-1.8, speed=5.0)
        assert deepest.peak_fz() <= 1.10 * 60.0
        assert off_the_gel(sim)


def test_a_refused_move_while_pressed_moves_nothing():
    sim, rig = open_sim("sphere10mm", 100.0, TRUE_SURFACE + 0.3)
    with sim, rig:
        rig.tare(10)
        with rig.motion("press") as m:
            m.jog("z", to=-1.0, speed=1.0)
        for target, speed in ((-4.0, 1.0), (-1.2, float("nan")), (-1.2, 1e6)):
            with pytest.raises(RigError, match="nothing was moved"), rig.motion("jog") as m:
                m.jog("z", to=target, speed=speed)
            assert rig.axes["z"].position() == pytest.approx(-1.0, abs=1e-4)  # still where it was asked to be


def test_a_damaged_state_file_is_one_line_and_leaves_the_devices_free(tmp_path, rig_state_dir):
    from common.errors import ConfigError
    from rig.rig_state import state_path

    sim = SimulatedRig(ManualClock())
    with sim:
        cfg_path = tmp_path / "rig.toml"
        cfg_path.write_text(sim.config_toml(with_camera=False))
        from rig.config import load_config

        cfg = load_config(cfg_path)
        state = state_path(str(cfg_path), cfg.name)
        state.parent.mkdir(parents=True, exist_ok=True)
        state.write_text('{"version": 1, "surface": {"z_mm": 1e999, "how": "x", "t_unix": 0}}')
        with pytest.raises(ConfigError, match=r"surface.z_mm\] must be 1 finite number"):
            Rig.open(cfg, sim.clock, axes=("z",))
        state.unlink()
        with Rig.open(cfg, sim.clock, axes=("z",)) as rig:  # nothing was left claimed or open
            assert rig.axes["z"].position() == pytest.approx(5.0, abs=1e-4)


def test_the_default_window_stiffness_covers_the_stiffest_library_object():
    from rig.config import DEFAULT_WINDOW_STIFFNESS_N_PER_MM

    sim = SimulatedRig(ManualClock(), indenter="plate20mm")
    with sim:
        contact = sim.world.contact
        f0 = float(contact.wrench(Pose(0.0, 0.0, -3.001, 0.0))[2])
        contact.reset()
        f1 = float(contact.wrench(Pose(0.0, 0.0, -3.002, 0.0))[2])
    assert (f1 - f0) / 0.001 <= DEFAULT_WINDOW_STIFFNESS_N_PER_MM
