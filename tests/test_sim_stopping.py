"""The simulated stages stop and re-target as motors do (docs/simulator.md, "Stopping").

A stop takes effect after the device's reaction time and then decelerates from the
current velocity; the stage is busy until at rest. A new target mid-move starts from
the current position and velocity. The Zaber and PR-drive simulators give their
device's values, shown over real ptys with the real drivers. The rigid plate is the
stiffest object of the library.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from objects.indenters import INDENTERS
from objects.pose import Pose
from rig.clock import ManualClock
from rig.drivers.pr_drive import PrDriveAxis
from rig.drivers.zaber import ZaberAxis, ZaberChain
from rig.sim.contact import SpringContact
from rig.sim.modbus_rtu import RtuServer
from rig.sim.motion import move_profile
from rig.sim.pr_drive_sim import EMERGENCY_DECEL_MS_PER_KRPM, FRAME_GAP_S, PROCESSING_S, PrDriveSim, krpm_ramp
from rig.sim.rig_sim import SimulatedRig
from rig.sim.stage import SimStage, StageSpec
from rig.sim.zaber_sim import ESTOP_ACCEL_NATIVE, REACTION_S, ZaberChainSim, ZaberDeviceSim
from rig.transport.modbus_bus import ModbusBus
from rig.transport.serial_link import SerialLink
from sensor_sim.profile import default_profile
from sensor_sim.world_contact import ElastomerContact

US = 0.047625e-3  # mm per Zaber microstep
TOL_MM = 1e-9  # float tolerance on positions built from a few phases

SPEC = StageSpec(
    travel=(0.0, 25.0), max_speed=5.0, accel=60.0, stop_decel=40.0, stop_reaction_s=0.003, abrupt_decel=6000.0
)


def cruising_stage(speed: float, clock: ManualClock) -> SimStage:
    """A stage moving at ``speed`` mm/s (cruising) at the clock's time, far from its target."""
    stage = SimStage("z", SPEC, position=1.0)
    stage.move_to(24.0, speed, clock.now())
    clock.advance(speed / SPEC.accel + 0.05)
    assert stage.velocity(clock.now()) == pytest.approx(speed)
    return stage


@pytest.mark.parametrize("speed", [0.01, 0.5, 2.0, 5.0])
def test_a_stop_at_speed_rests_after_reaction_plus_ramp_having_travelled_the_closed_form(speed):
    clock = ManualClock()
    stage = cruising_stage(speed, clock)
    t_stop, x_stop = clock.now(), stage.position(clock.now())
    stage.stop(t_stop)
    reaction, decel = SPEC.stop_reaction_s, SPEC.stop_decel
    t_rest = t_stop + reaction + speed / decel
    # the reaction: still at speed; then slowing at decel
    assert stage.velocity(t_stop + reaction * 0.5) == pytest.approx(speed)
    assert stage.velocity(t_stop + reaction + 0.5 * speed / decel) == pytest.approx(speed / 2)
    assert stage.busy(t_rest - 1e-9)
    assert not stage.busy(t_rest + 1e-9)
    travelled = stage.position(t_rest + 1.0) - x_stop
    assert travelled == pytest.approx(reaction * speed + speed**2 / (2 * decel), abs=TOL_MM)
    assert stage.stopping.distance(speed) == pytest.approx(travelled, abs=TOL_MM)


def test_an_emergency_stop_is_much_shorter_but_not_instant():
    clock = ManualClock()
    speed = 4.0
    soft, hard = cruising_stage(speed, clock), cruising_stage(speed, clock)
    t = clock.now()
    x_soft, x_hard = soft.position(t), hard.position(t)
    soft.stop(t)
    hard.stop(t, abrupt=True)
    assert hard.busy(t + SPEC.stop_reaction_s + 0.5 * speed / SPEC.abrupt_decel)
    soft_mm, hard_mm = soft.position(t + 10) - x_soft, hard.position(t + 10) - x_hard
    ramp_mm = hard_mm - SPEC.stop_reaction_s * speed
    assert ramp_mm == pytest.approx(speed**2 / (2 * SPEC.abrupt_decel), abs=TOL_MM) and ramp_mm > 0
    assert ramp_mm < (soft_mm - SPEC.stop_reaction_s * speed) / 20  # the reaction is the same


def test_stop_at_rest_and_after_the_move_ended_changes_nothing():
    clock = ManualClock()
    stage = SimStage("x", SPEC, position=3.0)
    stage.stop(clock.now())
    assert not stage.busy(clock.now()) and stage.position(clock.now()) == 3.0
    stage.move_to(3.01, 1.0, clock.now())  # a short move, over before the stop acts
    clock.advance(1.0)
    stage.stop(clock.now())
    assert not stage.busy(clock.now()) and stage.position(clock.now()) == pytest.approx(3.01)


def test_stall_stops_at_once_and_a_stop_never_leaves_the_travel():
    clock = ManualClock()
    stage = cruising_stage(3.0, clock)
    x = stage.position(clock.now())
    stage.stall(clock.now())
    assert not stage.busy(clock.now()) and stage.position(clock.now() + 1) == x
    edge = SimStage("x", StageSpec(travel=(0.0, 25.0), max_speed=5.0, accel=60.0, stop_decel=0.5), position=20.0)
    edge.move_to(25.0, 5.0, 0.0)
    edge.stop(0.9)  # 0.5 mm/s² would need 25 mm more: the limit switch stops it at the end
    assert edge.position(100.0) == pytest.approx(25.0)


def _continuous_at(stage: SimStage, t: float, dt: float = 1e-7) -> None:
    """Position and velocity just before ``t`` (the old profile) and after it match."""
    assert stage.position(t + dt) == pytest.approx(stage.position(t - dt), abs=1e-6)
    assert stage.velocity(t + dt) == pytest.approx(stage.velocity(t - dt), abs=1e-4)


@pytest.mark.parametrize(
    "new_target, new_speed",
    [(5.0, 2.0), (20.0, 4.0), (20.0, 0.5), (4.0, 2.0), (3.15, 2.0)],
    ids=["behind", "faster", "slower", "just-ahead", "too-close-to-stop"],
)
def test_a_re_target_mid_move_is_continuous_in_position_and_velocity(new_target, new_speed):
    stage = SimStage("x", StageSpec(travel=(0.0, 25.0), max_speed=5.0, accel=20.0), position=2.0)
    stage.move_to(20.0, 2.0, 0.0)
    t = 0.6  # cruising at 2 mm/s, at 3.1 mm
    before = (stage.position(t), stage.velocity(t))
    stage.move_to(new_target, new_speed, t)
    assert (stage.position(t), stage.velocity(t)) == pytest.approx(before)
    ts = np.linspace(t, t + 40.0, 40001)
    x, v = np.array([(stage.position(s), stage.velocity(s)) for s in ts]).T  # in time order, as a clock asks
    # no jump anywhere: steps bounded by the speed; the velocity changes at ≤ accel
    assert np.abs(np.diff(x)).max() <= max(2.0, new_speed) * (ts[1] - ts[0]) * 1.0001
    assert np.abs(np.diff(v)).max() <= 20.0 * (ts[1] - ts[0]) * 1.0001
    assert np.abs(v).max() <= max(2.0, new_speed) + 1e-9
    assert x[-1] == pytest.approx(new_target) and not stage.busy(ts[-1])
    if new_target < before[0] + 0.1:  # behind, or closer than the 0.1 mm it takes to stop: back through zero
        assert v.min() < 0


@settings(max_examples=300, deadline=None)
@given(
    x0=st.floats(-5, 5),
    v0=st.floats(-3, 3),
    target=st.floats(-5, 5),
    v_max=st.floats(0.05, 4),
    accel=st.floats(1, 100),
    decel=st.floats(1, 100),
)
def test_every_profile_from_a_moving_start_is_continuous_and_ends_at_rest_on_target(
    x0, v0, target, v_max, accel, decel
):
    p = move_profile(x0, v0, target, v_max, accel, decel, 1.0)
    assert p.position(1.0) == pytest.approx(x0, abs=1e-9) and p.velocity(1.0) == pytest.approx(v0, abs=1e-9)
    phases = p.phases()
    for (t0, x, v, a), (t1, x1, v1, _) in zip(phases, phases[1:]):
        assert x + (v + 0.5 * a * (t1 - t0)) * (t1 - t0) == pytest.approx(x1, abs=1e-9)
        assert v + a * (t1 - t0) == pytest.approx(v1, abs=1e-9)
    t0, x, v, a = phases[-1]
    span = p.t_end_s - t0
    assert x + (v + 0.5 * a * span) * span == pytest.approx(target, abs=1e-9)
    assert v + a * span == pytest.approx(0.0, abs=1e-9)
    assert p.position(p.t_end_s) == target and p.velocity(p.t_end_s) == 0.0
    assert all(abs(a) in (0.0, pytest.approx(accel), pytest.approx(decel)) for *_, a in phases)
    speeds = [abs(p.velocity(t)) for t in np.linspace(1.0, p.t_end_s, 64)]
    assert max(speeds) <= max(v_max, abs(v0)) + 1e-9


# -- the device simulators, with the real drivers over real ptys ------------------------------


@pytest.fixture
def zaber_x(world, manual_clock, serve):
    sim = ZaberChainSim(manual_clock, {1: ZaberDeviceSim(world.stages["x"], US)})
    chain = ZaberChain(SerialLink(serve(sim, manual_clock).url, baudrate=115200, timeout_s=0.3, device="chain"))
    yield ZaberAxis(chain, name="x", device=1, scale=US, offset=-12.5), sim.devices[1]
    chain.close()


def _stopped(axis, stage: SimStage, clock: ManualClock, stop, reaction_s: float, decel: float):
    """``stop()`` over the wire while cruising: busy until reaction + v/decel, then at rest.
    (position and speed at the command, distance travelled since, the driver's status at rest)."""
    x, v = stage.position(clock.now()), stage.velocity(clock.now())
    stop()
    assert axis.status().busy  # still moving (a Zaber replies BUSY): the reaction time, then the ramp
    clock.advance(reaction_s + abs(v) / decel - 1e-4)
    assert axis.status().busy
    clock.advance(2e-4)
    status = axis.status()
    assert not status.busy
    return x, v, stage.position(clock.now()) - x, status


def _zaber_stop_distance(axis: ZaberAxis, stage: SimStage, clock: ManualClock, command: str) -> tuple[float, float]:
    """Cruise at 2 mm/s, send ``command``; (speed at the command, distance until at rest)."""
    axis.move_to(axis.position() + 8.0, 2.0)
    clock.advance(1.0)
    decel = stage.stopping.abrupt_decel if command == "estop" else stage.stopping.decel
    _, v, travelled, _ = _stopped(axis, stage, clock, lambda: axis._cmd(command), REACTION_S, decel)
    return v, travelled


def test_zaber_stop_decelerates_at_its_accel_setting(zaber_x, world, manual_clock):
    axis, _ = zaber_x
    stage = world.stages["x"]
    # 205 data units = 205 × 10000/1.6384 µsteps/s² (manual, "accel") = 59.6 mm/s²
    decel = 205 * 10000 / 1.6384 * US
    assert stage.stopping.decel == pytest.approx(decel) and stage.spec.accel == pytest.approx(decel)
    assert decel == pytest.approx(59.59, abs=0.01)
    axis.move_to(axis.position() + 8.0, 2.0)
    manual_clock.advance(1.0)
    x, v, travelled, st_ = _stopped(axis, stage, manual_clock, axis.stop, REACTION_S, decel)  # the driver's stop
    assert travelled == pytest.approx(REACTION_S * v + v * v / (2 * decel), abs=TOL_MM)
    assert st_.position - (x - 12.5) == pytest.approx(travelled, abs=US)  # what the driver reads


def test_zaber_set_accel_changes_the_stop_and_estop_is_much_shorter(zaber_x, world, manual_clock):
    axis, _ = zaber_x
    stage = world.stages["x"]
    v, slow = _zaber_stop_distance(axis, stage, manual_clock, "stop")
    axis._cmd("set accel 410")  # twice the ramp: sets motion.accelonly and motion.decelonly
    assert axis._cmd("get motion.decelonly").data == "410"
    v2, fast = _zaber_stop_distance(axis, stage, manual_clock, "stop")
    assert v2 == pytest.approx(v)
    assert fast - REACTION_S * v == pytest.approx((slow - REACTION_S * v) / 2, abs=TOL_MM)
    v3, abrupt = _zaber_stop_distance(axis, stage, manual_clock, "estop")
    estop_decel = ESTOP_ACCEL_NATIVE * 10000 / 1.6384 * US
    assert abrupt == pytest.approx(REACTION_S * v3 + v3 * v3 / (2 * estop_decel), abs=TOL_MM)
    assert abrupt - REACTION_S * v3 < (slow - REACTION_S * v) / 20  # the ramps; the reaction is the same


def test_zaber_retarget_while_moving_keeps_the_velocity(zaber_x, world, manual_clock):
    axis, _ = zaber_x
    stage = world.stages["x"]
    axis.move_to(4.0, 2.0)
    manual_clock.advance(0.5)
    t = manual_clock.now()
    x, v = stage.position(t), stage.velocity(t)
    axis.move_to(-4.0, 2.0)  # behind: slows through zero and comes back
    assert (stage.position(t), stage.velocity(t)) == pytest.approx((x, v))
    manual_clock.advance(0.01)
    assert 0 < stage.velocity(manual_clock.now()) < v
    manual_clock.advance(20.0)
    assert axis.position() == pytest.approx(-4.0, abs=US)


@pytest.fixture
def pr_theta(world, manual_clock, serve):
    sim = PrDriveSim(world.stages["theta"], pulses_per_rev=10000, travel_per_rev=4.0)
    bus = ModbusBus(
        serve(RtuServer({2: sim}), manual_clock).url, baudrate=38400, timeout_s=0.3, retries=1, device="bus"
    )
    yield PrDriveAxis(
        bus, name="theta", device_id=2, pulses_per_rev=10000, travel_per_rev=4.0, offset=-180.0, unit="deg"
    )
    bus.close()


def test_pr_drive_emergency_stop_decelerates_at_its_emergency_ramp(pr_theta, world, manual_clock):
    stage = world.stages["theta"]
    decel = krpm_ramp(EMERGENCY_DECEL_MS_PER_KRPM, 4.0)  # 1000 rpm × 4 deg/rev in 50 ms: 1333 deg/s²
    assert decel == pytest.approx(1000 / 60 * 4 / 0.05)
    reaction = FRAME_GAP_S + PROCESSING_S
    assert stage.stopping.decel == pytest.approx(decel) and stage.stopping.reaction_s == pytest.approx(reaction)
    pr_theta.move_to(60.0, 20.0)
    manual_clock.advance(1.0)
    x, v, travelled, st_ = _stopped(pr_theta, stage, manual_clock, pr_theta.stop, reaction, decel)
    assert v == pytest.approx(20.0)
    assert travelled == pytest.approx(reaction * v + v * v / (2 * decel), abs=TOL_MM)
    assert st_.position - (x - 180.0) == pytest.approx(travelled, abs=4.0 / 10000)  # one pulse


def test_the_simulated_rig_tells_each_axis_stopping():
    with SimulatedRig(ManualClock(), contact=SpringContact()) as sim:
        stopping = sim.stopping()
    zaber = 205 * 10000 / 1.6384 * US
    for axis in ("x", "y", "z"):
        assert stopping[axis].decel == pytest.approx(zaber) and stopping[axis].reaction_s == REACTION_S
        assert stopping[axis].abrupt_decel > 100 * zaber
    assert stopping["theta"].decel == pytest.approx(krpm_ramp(EMERGENCY_DECEL_MS_PER_KRPM, 4.0))
    assert stopping["theta"].reaction_s == pytest.approx(FRAME_GAP_S + PROCESSING_S)
    assert stopping["z"].distance(1.0) == pytest.approx(REACTION_S + 1 / (2 * zaber))


# -- the rigid plate --------------------------------------------------------------------------


def test_the_plate_is_the_stiffest_library_object():
    """Fz at every depth, dF/dz in the gel (boards in full contact equal it) and at the window."""
    profile = default_profile()
    gel, geo = profile.gel(), profile.geometry(cells=96)
    depths = [0.3, 1.0, 2.4, 2.5, 2.8, 2.9]
    window = [3.0, 3.001]

    def curve(name):
        contact = ElastomerContact(name, gel, geo, tol=1e-6, tangential_tol=1e-6)
        out = []
        for d in depths + window:
            contact.reset()
            out.append(float(contact.wrench(Pose(0.0, 0.0, -d, 0.0))[2]))
        f = np.array(out)
        return f[: len(depths)], np.diff(f[2:4]) / 0.1, np.diff(f[4:6]) / 0.1, (f[-1] - f[-2]) / 0.001

    plate_f, plate_k_mid, plate_k_deep, plate_window = curve("plate20mm")
    assert geo.width_mm < 20.0 and geo.height_mm < 20.0  # the plate covers the pad
    for name in INDENTERS:
        if name == "plate20mm":
            continue
        f, k_mid, k_deep, window_k = curve(name)
        assert np.all(plate_f > f), name
        assert k_mid <= plate_k_mid * (1 + 1e-4) and k_deep <= plate_k_deep * (1 + 1e-4), name
        assert window_k < plate_window, name
    assert plate_k_deep == pytest.approx(plate_k_mid, rel=1e-4)  # a full-pad contact: linear
    assert plate_window > 500 * plate_k_deep  # past the gel: the window, ~57 N/µm
    assert math.isfinite(plate_window)
