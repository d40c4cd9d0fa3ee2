"""Zaber and PR-drive axes against their simulators over real ptys and sockets."""

import pytest

from rig.drivers.pr_drive import PrDriveAxis
from rig.drivers.zaber import ZaberAxis, ZaberChain
from rig.errors import DeviceFault, DeviceRejected
from rig.sim.modbus_rtu import RtuServer
from rig.sim.pr_drive_sim import PrDriveSim
from rig.sim.zaber_sim import ZaberChainSim, ZaberDeviceSim
from rig.transport.modbus_bus import ModbusBus
from rig.transport.serial_link import SerialLink

US = 0.047625e-3


@pytest.fixture(params=["pty", "tcp"])
def zaber(request, world, manual_clock, serve):
    sim = ZaberChainSim(manual_clock, {1: ZaberDeviceSim(world.stages["x"], US), 3: ZaberDeviceSim(world.stages["z"], US)})
    server = serve(sim, manual_clock, transport=request.param)
    chain = ZaberChain(SerialLink(server.url, baudrate=115200, timeout_s=0.3, device="chain"))
    yield chain, server
    chain.close()


def test_zaber_move_in_flight_then_done(zaber, world, manual_clock):
    chain, _ = zaber
    x = ZaberAxis(chain, name="x", device=1, scale=US, offset=-12.5)
    assert x.position() == pytest.approx(0.0, abs=US)
    x.move_to(2.0, 1.0)
    manual_clock.advance(1.0)  # held in flight: half-way-ish, still busy
    mid = x.status()
    assert mid.busy and 0.5 < mid.position < 2.0
    manual_clock.advance(5.0)
    done = x.status()
    assert not done.busy and done.position == pytest.approx(2.0, abs=US)
    assert world.pose().x_mm == pytest.approx(2.0, abs=US)


def test_zaber_negative_scale_flips_direction(zaber, world, manual_clock):
    chain, _ = zaber
    z = ZaberAxis(chain, name="z", device=3, scale=-US, offset=20.0)
    assert z.position() == pytest.approx(5.0, abs=US)
    z.move_to(-0.5, 2.0)
    manual_clock.advance(10)
    assert z.position() == pytest.approx(-0.5, abs=US)
    assert world.pose().depth_mm == pytest.approx(0.5, abs=US)


def test_zaber_rejection_is_typed_and_names_device_and_command(zaber):
    chain, _ = zaber
    x = ZaberAxis(chain, name="x", device=1, scale=US, offset=-12.5)
    with pytest.raises(DeviceRejected) as err:
        x.move_to(50.0, 1.0)  # beyond the stage's 25 mm travel
    assert err.value.reason == "BADDATA"
    assert "Zaber device 1" in str(err.value) and "move abs" in str(err.value)
    with pytest.raises(DeviceRejected, match="BADCOMMAND"):
        x._cmd("fly away")


def test_zaber_home_and_not_referenced_flag(zaber, world, manual_clock):
    chain, _ = zaber
    x = ZaberAxis(chain, name="x", device=1, scale=US, offset=-12.5)
    x.home()
    st = x.status()
    assert st.busy and not st.homed and "WR" in st.warnings
    manual_clock.advance(20)
    st = x.status()
    assert st.homed and st.position == pytest.approx(-12.5)


def test_zaber_stall_reported_as_fault_flag(zaber, world, manual_clock):
    chain, _ = zaber
    x = ZaberAxis(chain, name="x", device=1, scale=US, offset=-12.5)
    x.move_to(3.0, 1.0)
    manual_clock.advance(0.5)
    world.stages["x"].stall(manual_clock.now())
    st = x.status()
    assert "FS" in st.warnings
    assert x.faults(st) == ["FS (stalled and stopped)"]
    x.clear_warnings()
    assert x.faults(x.status()) == []


@pytest.fixture(params=["pty", "tcp"])
def pr_axis(request, world, manual_clock, serve):
    sim = PrDriveSim(world.stages["theta"], pulses_per_rev=10000, travel_per_rev=4.0)
    server = serve(RtuServer({2: sim}), manual_clock, transport=request.param)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=1, device="bus")
    axis = PrDriveAxis(bus, name="theta", device_id=2, pulses_per_rev=10000, travel_per_rev=4.0,
                       offset=-180.0, unit="deg")
    yield axis, sim, server
    bus.close()


def test_pr_drive_moves_and_reports(pr_axis, world, manual_clock):
    axis, _, _ = pr_axis
    axis.check_pulses_per_rev()
    assert axis.position() == pytest.approx(0.0)
    axis.move_to(-5.0, 10.0)
    manual_clock.advance(0.1)
    assert axis.status().busy
    manual_clock.advance(5)
    st = axis.status()
    assert not st.busy and st.position == pytest.approx(-5.0) and st.homed
    assert world.pose().theta_deg == pytest.approx(-5.0)


def test_pr_drive_wrong_scale_and_exception_codes(pr_axis):
    axis, sim, _ = pr_axis
    axis.pulses_per_rev = 4000
    with pytest.raises(DeviceFault, match="10000 pulses/rev but the config says 4000"):
        axis.check_pulses_per_rev()
    with pytest.raises(DeviceRejected, match=r"exception 2 \(ILLEGAL DATA ADDRESS\)"):
        axis._read(0x7777, 1)
    with pytest.raises(DeviceRejected, match=r"exception 3 \(ILLEGAL DATA VALUE\)"):
        PrDriveAxis(axis.bus, name="theta", device_id=2, pulses_per_rev=10000, travel_per_rev=4.0,
                    offset=-180.0, unit="deg").move_to(400.0, 10.0)  # beyond the stage's travel


def test_pr_drive_stall_alarm(pr_axis, world, manual_clock):
    axis, _, _ = pr_axis
    axis.move_to(10.0, 10.0)
    world.stages["theta"].stall(manual_clock.now())
    st = axis.status()
    assert axis.faults(st) == ["ALARM 0x0180"]


def test_two_drives_share_one_bus(world, manual_clock, serve):
    sims = {1: PrDriveSim(world.stages["x"], pulses_per_rev=2000, travel_per_rev=2.0),
            2: PrDriveSim(world.stages["y"], pulses_per_rev=2000, travel_per_rev=2.0)}
    server = serve(RtuServer(sims), manual_clock)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=0, device="bus")
    x = PrDriveAxis(bus, name="x", device_id=1, pulses_per_rev=2000, travel_per_rev=2.0, offset=-12.5)
    y = PrDriveAxis(bus, name="y", device_id=2, pulses_per_rev=2000, travel_per_rev=2.0, offset=-12.5)
    x.move_to(1.0, 2.0)
    y.move_to(-2.0, 2.0)
    manual_clock.advance(10)
    assert (x.position(), y.position()) == (pytest.approx(1.0), pytest.approx(-2.0))
    bus.close()
