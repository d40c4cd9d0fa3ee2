"""The rig on the simulated devices: safety armed on every move."""

import numpy as np
import pytest

from rig.clock import ManualClock
from rig.errors import DepthLimitError, DeviceFault, ForceLimitExceeded, SafetyError, SoftLimitError
from rig.rig import Rig
from rig.sim.rig_sim import SimulatedRig


@pytest.fixture
def sim():
    # Discrete-event time: every poll of the force guard and every deadline happens on
    # schedule however loaded the machine is (a clock running 20× real time can outrun
    # the polls on a busy 2-core machine and time a move out).
    with SimulatedRig(ManualClock()) as s:
        yield s


@pytest.fixture
def rig(sim):
    with Rig.open(sim.config(), sim.clock) as r:
        yield r


def test_status_has_four_axes_and_a_wrench(rig):
    st = rig.status()
    assert set(st.axes) == {"x", "y", "z", "theta"}
    assert st.axes["z"].position == pytest.approx(5.0, abs=1e-4)
    assert st.wrench is not None and np.isfinite(st.wrench.as_array()).all()


def test_soft_limit_refused_before_any_motion(rig, sim):
    before = {n: s.position(sim.clock.now()) for n, s in sim.world.stages.items()}
    with pytest.raises(SoftLimitError, match="nothing was moved"), rig.motion("test") as m:
        m.move({"x": 1.0, "z": -6.0}, 1.0)  # x is fine, z is not: neither moves
    after = {n: s.position(sim.clock.now()) for n, s in sim.world.stages.items()}
    assert before == after


def test_speed_above_axis_maximum_refused(rig):
    with pytest.raises(SafetyError, match="speed"), rig.motion("test") as m:
        m.jog("x", step=0.1, speed=50.0)


@pytest.fixture
def discrete():
    """The simulated rig on discrete-event time: every poll of the force guard happens on
    schedule however loaded the machine is (a 20× real-time clock can outrun the polls)."""
    with SimulatedRig(ManualClock()) as s, Rig.open(s.config(), s.clock) as r:
        yield r, s


def test_press_follows_physics_and_force_limit_trips(discrete):
    rig, sim = discrete
    rig.tare(10)
    with rig.motion("test") as m:
        m.move({"z": -1.0}, 2.0)
        expected = sim.world.true_wrench()[2]  # the elastomer solver's own answer at this pose
        assert 1.0 < expected < 10.0
        assert rig.gauge.read_fresh().fz_N == pytest.approx(expected, abs=0.05)
        m.move({"z": -1.5}, 2.0)
        assert rig.gauge.read_fresh().fz_N > expected  # deeper presses harder
        z_before = rig.axes["z"].position()
        with pytest.raises(DepthLimitError, match="depth guard allows 1.80 mm"):
            m.move({"z": -4.9}, 5.0)  # past the 3 mm gel: the indenter would reach the window
        assert rig.axes["z"].position() == z_before  # refused before anything moved
        rig.guard.limits[2] = rig.gauge.read_fresh().fz_N + 2.0  # a limit the gel itself reaches
        with pytest.raises(ForceLimitExceeded, match="Fz") as err:
            m.move({"z": -1.8}, 5.0)
        assert err.value.value > rig.guard.limits[2] - 0.5  # the read or the predicted load
        sim.clock.advance(0.1)  # a stopped stage comes to rest after its reaction and braking
        assert not any(s.busy(sim.clock.now()) for s in sim.world.stages.values())  # all stopped
        assert sim.world.true_wrench()[2] <= 1.1 * rig.guard.limits[2]  # the stop held the true load
        m.move({"z": 1.0}, 5.0)  # lifting z out of an overload is allowed; other moves are not
    assert rig.gauge.read_fresh().fz_N == pytest.approx(0.0, abs=0.05)


def test_over_the_limit_only_lifting_z_may_start(rig, sim):
    rig.tare(10)
    with rig.motion("test") as m:
        m.move({"z": -1.5}, 2.0)
        fz = rig.gauge.read_fresh().fz_N
        rig.guard.limits[2] = fz / 2  # now the present load is over the limit
        with pytest.raises(ForceLimitExceeded):
            m.move({"x": 0.5}, 1.0)
        with pytest.raises(ForceLimitExceeded):
            m.move({"z": -1.6}, 1.0)
        m.move({"z": 0.5}, 2.0)


def test_shear_and_twist_signs(rig):
    rig.tare(10)
    with rig.motion("test") as m:
        m.move({"z": -0.8}, 2.0)
        fz = rig.gauge.read_fresh().fz_N
        m.move({"y": 0.5}, 1.0)
        assert rig.gauge.read_fresh().fy_N > 0.2 * fz  # dragged along +y (partial slip: below μFz)
        m.move({"y": -0.5}, 1.0)
        assert rig.gauge.read_fresh().fy_N < -0.2 * fz  # reverses with the direction
        m.move({"y": 0.0}, 1.0)
        m.move({"theta": 5.0}, 5.0)
        assert rig.gauge.read_fresh().mz_Nmm > 0.1  # twist +θ: moment +Mz


def test_no_gauge_no_motion(sim):
    with Rig.open(sim.config(), sim.clock, gauge=False) as rig:
        with pytest.raises(SafetyError, match="no force gauge"):
            with rig.motion("jog") as m:
                m.jog("z", step=0.1)
        with pytest.raises(SafetyError, match="no force gauge"):
            with rig.motion("home") as m:
                m.home_axes()


def on_poll(rig, n, action):
    """Run ``action`` at the ``n``-th safety poll of the next move: an event mid-move."""
    calls = {"n": 0}
    original = rig.guard.check

    def check(wrench):
        calls["n"] += 1
        if calls["n"] == n:
            action()
        original(wrench)

    rig.guard.check = check


def test_stall_mid_move_is_a_fault_and_stops_everything(rig, sim):
    on_poll(rig, 3, lambda: sim.world.stages["x"].stall(sim.clock.now()))
    with pytest.raises(DeviceFault, match="FS"), rig.motion("test") as m:
        m.move({"x": 5.0, "y": 5.0}, 2.0)
    sim.clock.advance(0.1)  # a stopped stage decelerates after its reaction time (docs/simulator.md, "Stopping")
    assert not sim.world.stages["y"].busy(sim.clock.now())
    assert rig.axes["y"].position() < 5.0


def test_keyboard_interrupt_mid_move_stops_motion(rig, sim):
    def ctrl_c():
        raise KeyboardInterrupt

    on_poll(rig, 3, ctrl_c)
    with pytest.raises(KeyboardInterrupt), rig.motion("test") as m:
        m.move({"x": 10.0}, 2.0)
    sim.clock.advance(0.1)  # a stopped stage decelerates after its reaction time (docs/simulator.md, "Stopping")
    assert not sim.world.stages["x"].busy(sim.clock.now())
    assert 0.0 < rig.axes["x"].position() < 10.0


def test_home_goes_z_first_and_references(sim):
    order = []
    with Rig.open(sim.config(), sim.clock) as rig:
        for name, axis in rig.axes.items():
            original = axis.home
            axis.home = (lambda n, f: lambda: (order.append(n), f()))(name, original)
        with rig.motion("home") as m:
            m.home_axes()
        assert order[0] == "z"
        pos = rig.positions()
    assert pos["z"] == pytest.approx(20.0, abs=1e-4) and pos["x"] == pytest.approx(-12.5, abs=1e-4)


def test_faster_than_real_time_with_manual_clock():
    clock = ManualClock()
    with SimulatedRig(clock) as sim, Rig.open(sim.config(), clock, gauge=True) as rig:
        rig.gauge.stop_stream()  # a manual clock emits no stream on its own: poll instead
        t0 = clock.now()
        with rig.motion("test") as m:
            m.move({"x": 2.0}, 0.5)  # 4 s of simulated motion, no real waiting
        assert clock.now() - t0 >= 4.0
        assert rig.axes["x"].position() == pytest.approx(2.0, abs=1e-4)


def test_find_contact_on_the_simulated_gel(rig, sim):
    from rig.contact_search import find_contact

    found = find_contact(rig, threshold_N=0.05, speed_mm_s=1.0, max_travel_mm=8.0)
    # The gel surface is at z = 0; 0.05 N needs ~0.1 mm of a 10 mm sphere, plus one poll of motion.
    assert -0.2 < found.z_mm < 0.0 and abs(found.fz_N) >= 0.05
    assert rig.axes["z"].position() > found.z_mm + 0.4  # lifted clear
    assert abs(rig.gauge.read_fresh().fz_N) < 0.05


def test_find_contact_gives_up_cleanly(rig):
    from rig.contact_search import find_contact
    from rig.errors import RigError

    with pytest.raises(RigError, match="no contact down to z"):
        find_contact(rig, max_travel_mm=2.0)  # starts 5 mm above the gel
