"""FT300 and M8128 drivers against their simulators: polled reads, streams, tare."""

import numpy as np
import pytest

from rig.clock import SystemClock
from rig.drivers.ft300 import FT300
from rig.drivers.m8128 import M8128
from rig.errors import DeviceRejected
from rig.sim.ft300_sim import Ft300Sim
from rig.sim.m8128_sim import M8128Sim
from rig.sim.contact import SpringContact
from rig.sim.world import SimWorld
from rig.transport.modbus_bus import ModbusBus
from rig.transport.serial_link import SerialLink


@pytest.fixture
def live_world():
    return SimWorld(SystemClock(), contact=SpringContact())  # exact numbers for the driver layer


def press(world, depth_mm):
    """Put the indenter ``depth_mm`` into the gel, instantly."""
    world.stages["z"]._pos = world.spec.geometry["z"].origin + depth_mm


@pytest.fixture(params=["ft300", "m8128"])
def gauge(request, live_world, serve):
    clock = live_world.clock
    if request.param == "ft300":
        server = serve(Ft300Sim(live_world), clock)
        g = FT300(ModbusBus(server.url, baudrate=19200, timeout_s=0.3, retries=1, device="ft300"), clock)
    else:
        server = serve(M8128Sim(live_world), clock, transport="tcp")
        g = M8128(SerialLink(server.url, baudrate=115200, timeout_s=0.3, device="m8128"), clock)
        g.configure()
    yield g, server
    g.close()


def test_polled_read_matches_world(gauge, live_world):
    g, _ = gauge
    press(live_world, 1.0)
    w = g.read()
    expected = live_world.true_wrench() + np.array(live_world.spec.gauge_offset)
    np.testing.assert_allclose(w.as_array(), expected, atol=0.6)
    assert w.fz_N == pytest.approx(6.0 + 0.35, abs=0.05)  # placeholder spring: 6 N at 1 mm


def test_tare_removes_offset(gauge, live_world):
    g, _ = gauge
    bias = g.tare(10)
    np.testing.assert_allclose(bias, live_world.spec.gauge_offset, atol=0.6)
    assert abs(g.read().fz_N) < 0.05


def test_stream_rate_and_values(gauge, live_world):
    g, _ = gauge
    press(live_world, 0.5)
    g.start_stream()
    before = g.buffer.total
    assert g.buffer.wait_new(before, 50, timeout_s=3.0)
    samples = g.buffer.since(float("-inf"))
    times = [s.t_s for s in samples]
    assert times == sorted(times)
    fz = np.array([s.fz_N for s in samples[-20:]])
    assert np.all(np.abs(fz - (6.0 * 0.5**1.5 + 0.35)) < 0.05)
    g.stop_stream()
    assert g.read().fz_N == pytest.approx(6.0 * 0.5**1.5 + 0.35, abs=0.05)  # back to Modbus/ASCII polling


def test_stream_tare_uses_stream_samples(gauge, live_world):
    g, _ = gauge
    g.start_stream()
    g.tare(20)
    assert abs(g.read().fz_N) < 0.05
    press(live_world, 1.0)
    assert g.buffer.wait_new(g.buffer.total, 3, timeout_s=2.0)
    assert g.read().fz_N == pytest.approx(6.0, abs=0.05)


def test_ft300_identification(live_world, serve):
    server = serve(Ft300Sim(live_world), live_world.clock)
    g = FT300(ModbusBus(server.url, baudrate=19200, timeout_s=0.3, retries=0, device="ft300"), live_world.clock)
    assert g.identify() == {"firmware": "FT3.04", "serial": 100001, "year": 2024}
    g.close()


def test_m8128_bad_command_is_rejected(live_world, serve):
    server = serve(M8128Sim(live_world), live_world.clock)
    g = M8128(SerialLink(server.url, baudrate=115200, timeout_s=0.3, device="m8128"), live_world.clock)
    with pytest.raises(DeviceRejected, match="SMPF=99999"):
        g.command("AT+SMPF=99999")
    g.close()


def test_polled_read_after_a_stream(gauge, live_world):
    # Stopping a stream leaves no stream bytes behind for the next request's reply.
    g, _ = gauge
    press(live_world, 1.0)
    g.start_stream()
    assert g.buffer.wait_new(g.buffer.total, 5, timeout_s=2.0)
    g.stop_stream()
    for _ in range(3):
        assert g.read().fz_N == pytest.approx(6.0 + 0.35, abs=0.05)
