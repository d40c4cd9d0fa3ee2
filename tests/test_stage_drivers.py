"""Zaber and PR-drive axes against their simulators over real ptys and sockets."""

import pytest

from rig.drivers import zaber_ascii as za
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
    sim = ZaberChainSim(
        manual_clock, {1: ZaberDeviceSim(world.stages["x"], US), 3: ZaberDeviceSim(world.stages["z"], US)}
    )
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


# -- byte-exact exchanges with the Zaber simulator -------------------------------------
# Sources: Zaber ASCII protocol manual (zaber.com/protocol-manual?protocol=ascii),
# sections "Command Format", "Reply Format", "Message IDs", "Checksums", "Settings";
# and the lines zaber-motion 10.3.0 sends to identify a device (its log, docs/hardware.md).
# x starts at 12.5 mm = 262467 microsteps of 0.047625 µm; z at 15 mm = 314961.


def _exchange(link: SerialLink, command: bytes, n_replies: int = 1) -> list[bytes]:
    link.write(command, command.decode().strip())
    return [link.read_until(b"\n", command.decode().strip()) for _ in range(n_replies)]


@pytest.fixture
def zaber_link(zaber):
    chain, _ = zaber
    return chain.link


def test_zaber_answers_zaber_motion_identification_byte_exact(zaber_link):
    # Each line as zaber-motion 10.3.0 sends it: two-digit message id, checksum.
    table = [
        (b"/0 0 00:00\n", [b"@01 0 00 OK IDLE -- 0:0D\r\n", b"@03 0 00 OK IDLE -- 0:0B\r\n"]),
        (b"/1 0 01 get comm.packet.size.max:CF\n", [b"@01 0 01 OK IDLE -- 80:D4\r\n"]),
        (b"/1 0 02 get deviceid:40\n", [b"@01 0 02 OK IDLE -- 50030:43\r\n"]),  # X-LSM025A
        (b"/1 0 03 get system.serial:29\n", [b"@01 0 03 OK IDLE -- 33001:43\r\n"]),
        (b"/1 0 04 get version:75\n", [b"@01 0 04 OK IDLE -- 7.33:6E\r\n"]),
        (b"/1 0 05 get version.build:36\n", [b"@01 0 05 OK IDLE -- 16000:41\r\n"]),
        # A setting newer than the modelled firmware: rejected, and zaber-motion carries on.
        (b"/1 0 06 get device.hw.modified:8D\n", [b"@01 0 06 RJ IDLE -- BADCOMMAND:6F\r\n"]),
        (b"/1 0 10 get system.axiscount:CD\n", [b"@01 0 10 OK IDLE -- 1:0B\r\n"]),
        (b"/1 1 11 get resolution:28\n", [b"@01 1 11 OK IDLE -- 64:D0\r\n"]),
        # An integrated stage has no peripheral: rejected, zaber-motion then treats it as integrated.
        (b"/1 1 12 get peripheralid:82\n", [b"@01 1 12 RJ IDLE -- BADCOMMAND:71\r\n"]),
    ]
    for command, replies in table:
        assert _exchange(zaber_link, command, len(replies)) == replies, command


def test_zaber_command_without_address_goes_to_every_device_in_address_order(zaber_link):
    # Manual, "Command Format": device and axis are optional; no address means all devices.
    assert _exchange(zaber_link, b"/get pos\n", 2) == [b"@01 0 OK IDLE -- 262467\r\n", b"@03 0 OK IDLE -- 314961\r\n"]
    assert _exchange(zaber_link, b"/3 get pos\n") == [b"@03 0 OK IDLE -- 314961\r\n"]


def test_zaber_one_digit_message_id_is_answered_with_two(zaber_link):
    # Manual, "Message IDs": an id of 0-99 after device and axis, echoed in the reply.
    assert _exchange(zaber_link, b"/1 1 5 get pos\n") == [b"@01 1 05 OK IDLE -- 262467\r\n"]


def test_zaber_driver_sends_padded_ids_and_accepts_one_digit_replies():
    assert za.format_command(1, 1, "get pos", 5, True) == b"/1 1 05 get pos:27\n"
    reply = za.parse_reply(b"@01 1 5 OK IDLE -- 262467\r\n")
    assert (reply.message_id, reply.data) == (5, "262467")
    assert za.parse_reply(b"@01 1 05 OK IDLE -- 0\r\n").message_id == 5


def test_zaber_device_setting_of_an_axis_is_deviceonly(zaber_link):
    assert _exchange(zaber_link, b"/1 1 get deviceid\n") == [b"@01 1 RJ IDLE -- DEVICEONLY\r\n"]


def test_zaber_move_vel_runs_until_stop(zaber_link, world, manual_clock):
    # 34402 = 1 mm/s: 1 / 0.047625e-3 µsteps/s × 1.6384 (manual, "move vel", "maxspeed").
    assert _exchange(zaber_link, b"/1 1 move vel 34402\n") == [b"@01 1 OK BUSY -- 0\r\n"]
    manual_clock.advance(2.0)
    # A stopping stage decelerates (at its accel setting, 205 = 59.6 mm/s²) and replies BUSY.
    assert _exchange(zaber_link, b"/1 1 stop\n") == [b"@01 1 OK BUSY -- 0\r\n"]
    moved = world.stages["x"].position(manual_clock.now()) - 12.5
    assert 1.9 < moved < 2.0  # 2 s at 1 mm/s less the 17 ms ramp up
    manual_clock.advance(0.1)  # the 1 ms reaction and the 17 ms ramp down
    assert _exchange(zaber_link, b"/1 1 get pos\n")[0].startswith(b"@01 1 OK IDLE")
    assert _exchange(zaber_link, b"/1 1 move vel -34402\n") == [b"@01 1 OK BUSY -- 0\r\n"]
    manual_clock.advance(60.0)  # stops at the travel's end
    assert _exchange(zaber_link, b"/1 1 get pos\n") == [b"@01 1 OK IDLE -- 0\r\n"]


def test_zaber_settings_zaber_motion_reads_and_writes(zaber_link, world, manual_clock):
    assert _exchange(zaber_link, b"/1 1 get limit.max\n") == [b"@01 1 OK IDLE -- 524934\r\n"]  # 25 mm
    assert _exchange(zaber_link, b"/1 1 get accel\n") == [b"@01 1 OK IDLE -- 205\r\n"]
    assert _exchange(zaber_link, b"/1 1 set accel 300\n") == [b"@01 1 OK IDLE -- 0\r\n"]
    assert _exchange(zaber_link, b"/1 1 get accel\n") == [b"@01 1 OK IDLE -- 300\r\n"]
    # set pos re-references without moving the carriage (manual, "pos").
    assert _exchange(zaber_link, b"/1 1 set pos 1000\n") == [b"@01 1 OK IDLE -- 0\r\n"]
    assert _exchange(zaber_link, b"/1 1 get pos\n") == [b"@01 1 OK IDLE -- 1000\r\n"]
    assert world.stages["x"].position(manual_clock.now()) == pytest.approx(12.5)
    assert _exchange(zaber_link, b"/1 1 move abs 2000\n") == [b"@01 1 OK BUSY -- 0\r\n"]
    manual_clock.advance(5.0)
    assert world.stages["x"].position(manual_clock.now()) == pytest.approx(12.5 + 1000 * US)


@pytest.fixture(params=["pty", "tcp"])
def pr_axis(request, world, manual_clock, serve):
    sim = PrDriveSim(world.stages["theta"], pulses_per_rev=10000, travel_per_rev=4.0)
    server = serve(RtuServer({2: sim}), manual_clock, transport=request.param)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=1, device="bus")
    axis = PrDriveAxis(
        bus, name="theta", device_id=2, pulses_per_rev=10000, travel_per_rev=4.0, offset=-180.0, unit="deg"
    )
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
        PrDriveAxis(
            axis.bus, name="theta", device_id=2, pulses_per_rev=10000, travel_per_rev=4.0, offset=-180.0, unit="deg"
        ).move_to(400.0, 10.0)  # beyond the stage's travel


def test_pr_drive_stall_alarm(pr_axis, world, manual_clock):
    axis, _, _ = pr_axis
    axis.move_to(10.0, 10.0)
    world.stages["theta"].stall(manual_clock.now())
    st = axis.status()
    assert axis.faults(st) == ["ALARM 0x0180"]


def test_two_drives_share_one_bus(world, manual_clock, serve):
    sims = {
        1: PrDriveSim(world.stages["x"], pulses_per_rev=2000, travel_per_rev=2.0),
        2: PrDriveSim(world.stages["y"], pulses_per_rev=2000, travel_per_rev=2.0),
    }
    server = serve(RtuServer(sims), manual_clock)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=0, device="bus")
    x = PrDriveAxis(bus, name="x", device_id=1, pulses_per_rev=2000, travel_per_rev=2.0, offset=-12.5)
    y = PrDriveAxis(bus, name="y", device_id=2, pulses_per_rev=2000, travel_per_rev=2.0, offset=-12.5)
    x.move_to(1.0, 2.0)
    y.move_to(-2.0, 2.0)
    manual_clock.advance(10)
    assert (x.position(), y.position()) == (pytest.approx(1.0), pytest.approx(-2.0))
    bus.close()


def test_pr_drive_motion_state_bits_follow_the_manual(pr_axis, world, manual_clock):
    # 0x1003 "Motion state" (Status Monitoring Parameters): bit1 enabled, bit2 running,
    # bit4 command completed, bit5 path completed, bit6 homing completed, bit0 fault.
    axis, sim, _ = pr_axis
    (state,) = axis._read(0x1003, 1)
    assert state == 0x0002 | 0x0040  # enabled; the world's stages start homed
    axis.move_to(3.0, 10.0)
    (state,) = axis._read(0x1003, 1)
    assert state & 0x0004 and not state & 0x0030
    manual_clock.advance(5)
    (state,) = axis._read(0x1003, 1)
    assert state == 0x0002 | 0x0010 | 0x0020 | 0x0040
    world.stages["theta"].stall(manual_clock.now())
    (state,) = axis._read(0x1003, 1)
    assert state & 0x0001
    assert axis._read(0x1012, 4)[0:2] == axis._read(0x1014, 2)  # profile = feedback: no following error


def test_pr_drive_single_frame_with_delay_and_trigger_moves_the_stage(pr_axis, world, manual_clock):
    # PR0 written register by register stores; the frame's last register (0x6207,
    # mapped to 0x6002) triggers. A relative path (mode 0x0041) adds to the position.
    axis, sim, _ = pr_axis
    axis.bus.write_registers(2, 0x6200, [0x0041, 0, 2500, 60, 100, 100, 0, 0x0000], device="theta")
    manual_clock.advance(2)
    assert axis.position() == pytest.approx(0.0)  # 0x6207 = 0: stored, not run
    axis.bus.write_registers(2, 0x6207, [0x0010], device="theta")
    manual_clock.advance(5)
    assert axis.position() == pytest.approx(1.0)  # 2500 pulses at 4 deg / 10000 pulses
    assert world.pose().theta_deg == pytest.approx(1.0)


def test_modbus_broadcast_write_is_carried_out_by_every_drive_and_unanswered(world, manual_clock, serve):
    # Modbus over Serial Line v1.02 §2.1: address 0 is the broadcast; writes only, no reply.
    from rig.errors import DeviceTimeout
    from rig.transport.crc import append_crc

    sims = {
        1: PrDriveSim(world.stages["x"], pulses_per_rev=2000, travel_per_rev=2.0),
        2: PrDriveSim(world.stages["y"], pulses_per_rev=2000, travel_per_rev=2.0),
    }
    server = serve(RtuServer(sims), manual_clock)
    link = SerialLink(server.url, baudrate=38400, timeout_s=0.2, device="bus")
    link.write(append_crc(bytes.fromhex("00 06 62 03 00 78")), "broadcast 120 rpm")
    with pytest.raises(DeviceTimeout, match="no reply"):
        link.read_exact(8, "broadcast")
    assert [s.regs[0x6203] for s in sims.values()] == [120, 120]
    link.close()


def test_pr_drive_software_limits_are_set_read_back_and_stop_a_path(pr_axis, world, manual_clock):
    """The drive's software limits (Pr8.00 bit1, Pr8.06-Pr8.09: registers ASSUMED in
    rig/drivers/pr_registers.py) hold a z floor on a PR-mode axis: set and read back by the
    driver, a path beyond them stops at them, and the int32 extremes disable them again."""
    axis, sim, _ = pr_axis
    assert axis.native_limits() == (-(2**31), 2**31 - 1)  # disabled at power-up
    low, high = axis.native_range(-10.0, 5.0)
    assert (low, high) == (425000, 462500)  # -10 and +5 deg, counted from -180 deg at 2500 pulses per deg
    axis.set_native_limits(low, high)
    assert axis.native_limits() == (low, high) and sim.soft_limits() == (low, high)
    axis.move_to(8.0, 10.0)
    manual_clock.advance(5)
    assert axis.position() == pytest.approx(5.0) and world.pose().theta_deg == pytest.approx(5.0)
    axis.set_native_limits(-(2**31), 2**31 - 1)
    assert sim.soft_limits() is None
    axis.move_to(8.0, 10.0)
    manual_clock.advance(5)
    assert axis.position() == pytest.approx(8.0)
