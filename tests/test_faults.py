"""Injected faults end in a typed error or a recovered read: never a hang, never a wrong value."""

import time

import numpy as np
import pytest

from rig.clock import SystemClock
from rig.drivers.ft300 import FT300
from rig.drivers.m8128 import M8128
from rig.drivers.pr_drive import PrDriveAxis
from rig.drivers.zaber import ZaberAxis, ZaberChain
from rig.errors import DeviceDisconnected, DeviceError, DeviceTimeout
from rig.sim.contact import SpringContact
from rig.sim.ft300_sim import Ft300Sim
from rig.sim.m8128_sim import M8128Sim
from rig.sim.modbus_rtu import RtuServer
from rig.sim.pr_drive_sim import PrDriveSim
from rig.sim.world import SimWorld
from rig.sim.zaber_sim import ZaberChainSim, ZaberDeviceSim
from rig.transport.modbus_bus import ModbusBus
from rig.transport.serial_link import SerialLink

US = 0.047625e-3


@pytest.fixture
def zaber_x(world, manual_clock, serve):
    server = serve(ZaberChainSim(manual_clock, {1: ZaberDeviceSim(world.stages["x"], US)}), manual_clock)
    chain = ZaberChain(SerialLink(server.url, baudrate=115200, timeout_s=0.15, device="chain"), retries=2)
    yield ZaberAxis(chain, name="x", device=1, scale=US, offset=-12.5), chain, server
    chain.close()


@pytest.mark.parametrize("fault", ["drop_next", "garble_next", "truncate_next"])
def test_zaber_single_fault_recovers_with_the_right_value(zaber_x, manual_clock, fault):
    x, chain, server = zaber_x
    x.move_to(1.234, 5.0)
    manual_clock.advance(5.0)
    getattr(server.faults, fault)(1)
    assert x.position() == pytest.approx(1.234, abs=US)  # never a corrupted number
    assert chain.recovered == 1


def test_zaber_late_reply_is_not_taken_for_the_next_answer(zaber_x):
    x, chain, server = zaber_x
    server.faults.delay_next(1, 0.25)  # beyond the 0.15 s timeout: arrives during the retry
    assert x.position() == pytest.approx(0.0, abs=US)
    assert chain.recovered == 1
    assert x.position() == pytest.approx(0.0, abs=US)  # the stale reply was skipped by message id


def test_zaber_persistent_silence_is_a_timeout_in_bounded_time(zaber_x):
    x, _, server = zaber_x
    server.faults.drop_next(100)
    t = time.monotonic()
    with pytest.raises(DeviceTimeout, match="no reply within"):
        x.position()
    assert time.monotonic() - t < 1.0  # 3 tries × 0.15 s


def test_zaber_persistent_garbling_is_a_framing_error(zaber_x):
    from rig.errors import FramingError

    x, _, server = zaber_x
    server.faults.garble_next(100)
    with pytest.raises((FramingError, DeviceTimeout)):
        x.position()


def test_zaber_device_vanishes(zaber_x):
    x, _, server = zaber_x
    assert x.position() == pytest.approx(0.0, abs=US)
    server.disconnect()
    with pytest.raises((DeviceDisconnected, DeviceTimeout)) as err:
        x.position()
    assert "Zaber" in str(err.value) or "chain" in str(err.value)


@pytest.fixture
def pr_theta(world, manual_clock, serve):
    server = serve(
        RtuServer({1: PrDriveSim(world.stages["theta"], pulses_per_rev=10000, travel_per_rev=4.0)}), manual_clock
    )
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.15, retries=2, device="bus")
    yield (
        PrDriveAxis(
            bus, name="theta", device_id=1, pulses_per_rev=10000, travel_per_rev=4.0, offset=-180.0, unit="deg"
        ),
        server,
    )
    bus.close()


@pytest.mark.parametrize("fault", ["drop_next", "garble_next", "truncate_next"])
def test_modbus_single_fault_recovers(pr_theta, fault):
    axis, server = pr_theta
    getattr(server.faults, fault)(1)
    assert axis.position() == pytest.approx(0.0)


def test_modbus_silence_is_a_timeout(pr_theta):
    axis, server = pr_theta
    server.faults.drop_next(100)
    t = time.monotonic()
    with pytest.raises(DeviceTimeout, match="theta"):
        axis.position()
    assert time.monotonic() - t < 2.0


def test_modbus_device_vanishes(pr_theta):
    axis, server = pr_theta
    server.disconnect()
    with pytest.raises((DeviceDisconnected, DeviceTimeout)):
        axis.position()


@pytest.fixture(params=["ft300", "m8128"])
def streaming_gauge(request, serve):
    world = SimWorld(SystemClock(), contact=SpringContact())
    world.stages["z"]._pos = world.spec.geometry["z"].origin + 1.0  # 1 mm pressed: Fz = 6 N + bias
    if request.param == "ft300":
        server = serve(Ft300Sim(world), world.clock)
        g = FT300(ModbusBus(server.url, baudrate=19200, timeout_s=0.2, retries=1, device="ft300"), world.clock)
    else:
        server = serve(M8128Sim(world), world.clock)
        g = M8128(SerialLink(server.url, baudrate=115200, timeout_s=0.2, device="m8128"), world.clock)
    g.start_stream()
    yield g, server
    try:
        g.close()
    except DeviceError:
        pass  # the vanished-device test closed the port under it


def test_stream_crc_errors_cost_frames_not_values(streaming_gauge):
    g, server = streaming_gauge
    assert g.buffer.wait_new(g.buffer.total, 5, timeout_s=2.0)
    server.faults.garble_next(20)
    before = g.buffer.total
    assert g.buffer.wait_new(before, 40, timeout_s=3.0)
    stats = g.stream_stats()
    assert stats["frames_bad"] + stats["bytes_skipped"] > 0
    fz = np.array([s.fz_N for s in g.buffer.since(float("-inf"))])
    assert np.all(np.abs(fz - 6.35) < 0.05), "a corrupted frame leaked a wrong value"


def test_stream_dropped_frames_are_gaps_not_values(streaming_gauge):
    g, server = streaming_gauge
    server.faults.drop_next(10)
    before = g.buffer.total
    assert g.buffer.wait_new(before, 20, timeout_s=3.0)
    assert g.read_raw().fz_N == pytest.approx(6.35, abs=0.05)


def test_stream_device_vanishes_is_raised_to_the_reader(streaming_gauge):
    g, server = streaming_gauge
    server.disconnect()
    with pytest.raises((DeviceDisconnected, DeviceTimeout)):
        for _ in range(200):  # a fresh read fails within the stale window, not a hang
            g.read()
            g.buffer.wait_new(g.buffer.total, 1, timeout_s=0.05)


def test_modbus_stalled_simulator_is_waited_for_not_timed_out(pr_theta, manual_clock):
    axis, server = pr_theta
    server.faults.stall_next(1, 0.5)  # the simulator thread stalls 0.5 s of real time, beyond the 0.15 s timeout
    t_sim = manual_clock.now()
    assert axis.position() == pytest.approx(0.0)
    assert server.faults.counts.stalled == 1
    assert manual_clock.now() == t_sim  # no simulated time passed: the device answered at once


def test_modbus_late_reply_is_skipped_not_used(pr_theta, manual_clock):
    axis, server = pr_theta
    axis.move_to(5.0, 1000.0)
    manual_clock.advance(5.0)
    server.faults.delay_next(1, 0.2)  # the position reply comes 0.2 s late: the status read follows
    assert axis.position() == pytest.approx(5.0)  # retried after the 0.15 s timeout
    manual_clock.advance(0.1)  # the late position reply is out on the wire now
    for _ in range(3):
        status = axis.status()  # each read gets its own reply, never the late position
        assert status.warnings == () and status.position == pytest.approx(5.0)
