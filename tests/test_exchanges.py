"""The real drivers write exactly the bytes the manuals describe (scripted device on a pty)."""

import numpy as np
import pytest

from rig.clock import SystemClock
from rig.drivers import ft300
from rig.drivers import zaber_ascii as za
from rig.drivers.ft300 import FT300
from rig.drivers.pr_drive import PrDriveAxis
from rig.drivers.zaber import ZaberAxis, ZaberChain
from rig.sim.link import RequestReplyDevice
from rig.sim.modbus_rtu import RtuServer
from rig.sim.pr_drive_sim import PrDriveSim
from rig.sim.scripted import ScriptedDevice
from rig.transport.crc import append_crc
from rig.transport.modbus_bus import ModbusBus
from rig.transport.serial_link import SerialLink


def zaber_reply(body: str) -> bytes:
    return f"@{body}:{za.checksum(body)}\r\n".encode()


def test_zaber_move_writes_speed_then_absolute_target(serve):
    us = 0.047625e-3
    script = ScriptedDevice(
        [
            (za.format_command(1, 1, "set maxspeed 34402", 0, True), zaber_reply("01 1 00 OK IDLE -- 0")),
            (za.format_command(1, 1, "move abs 20997", 1, True), zaber_reply("01 1 01 OK BUSY -- 0")),
            (za.format_command(1, 1, "get pos", 2, True), zaber_reply("01 1 02 OK BUSY -- 10000")),
        ]
    )
    server = serve(script)
    chain = ZaberChain(SerialLink(server.url, baudrate=115200, timeout_s=0.3, device="chain"))
    axis = ZaberAxis(chain, name="x", device=1, scale=us, offset=0.0)
    # 1 mm = 20997.375 microsteps -> 20997; 1 mm/s × 1.6384 speed units per microstep/s = 34401.9 -> 34402
    axis.move_to(1.0, 1.0)
    assert axis.position() == pytest.approx(10000 * us)
    chain.close()
    script.check()


def test_pr_drive_move_is_one_immediate_trigger_frame(serve):
    # Leadshine CS2RS manual, "Immediate Trigger": PR0 = Pr9.00..Pr9.07 in one fc 16
    # (mode, position high/low, velocity, acceleration, deceleration, delay, trigger
    # 0x0010). Target 12500 pulses (5 deg at 4 deg/rev, 10000 pulses/rev), 75 rpm,
    # 100 ms ramps, no delay. Position read back from 0x1012/0x1013 (profile position,
    # "Status Monitoring Parameters"), state from 0x1003 (bit2 running, bit6 homed).
    frame = append_crc(bytes.fromhex("01 10 62 00 00 08 10 00 01 00 00 30 D4 00 4B 00 64 00 64 00 00 00 10"))
    script = ScriptedDevice(
        [
            (frame, append_crc(bytes.fromhex("01 10 62 00 00 08"))),
            (append_crc(bytes.fromhex("01 03 10 03 00 01")), append_crc(bytes.fromhex("01 03 02 00 46"))),
            (append_crc(bytes.fromhex("01 03 10 12 00 02")), append_crc(bytes.fromhex("01 03 04 00 00 30 D4"))),
        ]
    )
    server = serve(script)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=0, device="bus")
    axis = PrDriveAxis(bus, name="theta", device_id=1, pulses_per_rev=10000, travel_per_rev=4.0, unit="deg")
    axis.move_to(5.0, 5.0)
    st = axis.status()  # 0x0046: enabled, running, homed
    assert st.busy and st.homed and st.position == pytest.approx(5.0) and st.warnings == ()
    bus.close()
    script.check()


def test_pr_drive_simulator_answers_the_manuals_pr0_frame_byte_for_byte(world, manual_clock, serve):
    # Leadshine CS2RS manual, "Immediate Trigger", example (drive id 7), every byte
    # including the CRC as printed. Its Pr9.03 word is 0x0000 although the text says
    # 200 rpm; the simulator echoes it as the manual's drive does and does not move.
    drive = PrDriveSim(world.stages["theta"], pulses_per_rev=10000, travel_per_rev=4.0)
    server = serve(RtuServer({7: drive}), manual_clock)
    link = SerialLink(server.url, baudrate=38400, timeout_s=0.3, device="drive")
    link.write(bytes.fromhex("07 10 62 00 00 08 10 00 01 00 00 27 10 00 00 27 10 27 10 00 00 00 10 8D 50"), "PR0")
    assert link.read_exact(8, "PR0") == bytes.fromhex("07 10 62 00 00 08 DE 11")
    assert drive.read_registers(0x6200, 8, manual_clock.now()) == [1, 0, 10000, 0, 10000, 10000, 0, 0x10]
    link.close()


def test_pr_drive_simulator_rejects_undocumented_readback_registers(world, manual_clock, serve):
    # 0x602A/B (the old read-back) and 0x602C (a third-party driver's) are in no manual
    # table found: exception 2, ILLEGAL DATA ADDRESS (Modbus Application Protocol §7).
    drive = PrDriveSim(world.stages["theta"], pulses_per_rev=10000, travel_per_rev=4.0)
    server = serve(RtuServer({1: drive}), manual_clock)
    link = SerialLink(server.url, baudrate=38400, timeout_s=0.3, device="drive")
    for address in ("60 2A", "60 2C"):
        link.write(append_crc(bytes.fromhex(f"01 03 {address} 00 02")), "read")
        assert link.read_exact(5, "read") == append_crc(bytes.fromhex("01 83 02"))
    link.close()


def test_ft300_poll_and_stream_start_bytes(serve):
    script = ScriptedDevice(
        [
            # Read 6 registers from 180 (0xB4) of device 9: Fx 1.00 N, Fy -2.50 N, Fz 12.34 N, Mz 1 N·mm.
            (
                append_crc(bytes.fromhex("09 03 00 B4 00 06")),
                append_crc(bytes.fromhex("09 03 0C 00 64 FF 06 04 D2 00 7B FF CE 00 01")),
            ),
            # The manual's start-stream request, byte for byte.
            (bytes.fromhex("09 10 01 9A 00 01 02 02 00 CD CA"), append_crc(bytes.fromhex("09 10 01 9A 00 01"))),
        ]
    )
    server = serve(script)
    bus = ModbusBus(server.url, baudrate=19200, timeout_s=0.3, retries=0, device="bus")
    gauge = FT300(bus, SystemClock())
    np.testing.assert_allclose(gauge.read().as_array(), [1.0, -2.5, 12.34, 123.0, -50.0, 1.0])
    gauge._stream_open()
    bus.close()
    script.check()


def test_harness_fails_on_unconsumed_exchange(serve):
    script = ScriptedDevice([(b"/1 1 get pos\n", b"@01 1 OK IDLE -- 0\r\n")])
    with pytest.raises(AssertionError, match="never happened"):
        script.check()


def test_ft300_stream_stop_is_fifty_0xff_bytes(serve):
    # FT300 manual: stream mode ends on a run of 0xFF bytes (about 50); nothing is answered.
    script = ScriptedDevice(
        [
            (bytes.fromhex("09 10 01 9A 00 01 02 02 00 CD CA"), append_crc(bytes.fromhex("09 10 01 9A 00 01"))),
            (b"\xff" * 50, b""),
        ]
    )
    server = serve(script)
    bus = ModbusBus(server.url, baudrate=19200, timeout_s=0.3, retries=0, device="bus")
    gauge = FT300(bus, SystemClock())
    gauge.start_stream()
    gauge.stop_stream()
    bus.close()
    script.check()


def test_modbus_read_input_and_write_single_bytes(serve):
    # Modbus Application Protocol v1.1b3 §6.4 (fc 4) and §6.6 (fc 6, reply echoes the request).
    write = append_crc(bytes.fromhex("01 06 60 02 00 40"))
    script = ScriptedDevice(
        [
            (append_crc(bytes.fromhex("09 04 00 B4 00 02")), append_crc(bytes.fromhex("09 04 04 FF FF 00 02"))),
            (write, write),
        ]
    )
    server = serve(script)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=0, device="bus")
    assert bus.read_input(9, 0xB4, 2, device="gauge") == [0xFFFF, 0x0002]
    bus.write_register(1, 0x6002, 0x0040, device="drive")
    bus.close()
    script.check()


def test_ft300_identification_requests_are_robotiqs(serve):
    # rq_sensor_com.c, rq_sensor_com_read_info_high_lvl: fc 3 from 500 (3 registers),
    # 514 (1 register), 510 (4 registers); here in the driver's order 500, 510, 514.
    script = ScriptedDevice(
        [
            (append_crc(bytes.fromhex("09 03 01 F4 00 03")), append_crc(bytes.fromhex("09 03 06 46 54 53 01 00 03"))),
            (
                append_crc(bytes.fromhex("09 03 01 FE 00 04")),
                append_crc(bytes.fromhex("09 03 08 46 54 53 00 86 A1 00 01")),
            ),
            (append_crc(bytes.fromhex("09 03 02 02 00 01")), append_crc(bytes.fromhex("09 03 02 07 E8"))),
        ]
    )
    server = serve(script)
    gauge = FT300(ModbusBus(server.url, baudrate=19200, timeout_s=0.3, retries=0, device="bus"), SystemClock())
    # "%c%c%c-%hhu.%hhu.%hhu"; serial = reg513 << 16 | reg512 = 0x000186A1, "%c%c%c-%.4lu"
    assert gauge.identify() == {"firmware": "FTS-1.0.3", "serial": "FTS-100001", "serial_number": 100001, "year": 2024}
    gauge.bus.close()
    script.check()


def test_ft300_serial_zero_is_unknown_and_short_numbers_are_padded():
    # rq_sensor_com.c prints "UNKNOWN" for a zero serial number, "%.4lu" otherwise.
    assert ft300.decode_serial([0x4654, 0x5300, 0, 0]) == ("UNKNOWN", 0)
    assert ft300.decode_serial([0x4654, 0x5300, 42, 0]) == ("FTS-0042", 42)
    assert ft300.decode_serial([0x4654, 0x5300, 0x0000, 0x0001]) == ("FTS-65536", 65536)  # high word is 513


class LeftStreaming(RequestReplyDevice):
    """A sensor streaming since before the host opened the port: frames until it has
    heard the jam signal, then the scripted Modbus exchanges."""

    def __init__(self, after: ScriptedDevice):
        self.after = after
        self.heard = b""
        self.streaming = True

    def feed(self, data, now_s):
        if not self.streaming:
            return self.after.feed(data, now_s)
        self.heard += data
        if self.heard.endswith(ft300.STOP_BYTES):
            self.streaming = False
        return []

    def tick_interval_s(self):
        return 0.01 if self.streaming else None

    def tick(self, now_s):
        return [ft300.encode_stream_frame(np.array([0, 0, 1.0, 0, 0, 0]))] if self.streaming else []


def test_ft300_open_stops_a_leftover_stream_with_fifty_0xff_then_talks_modbus(serve):
    # rq_sensor_com.c, rq_com_tentative_connexion: listen; if bytes arrive, send the
    # jam signal (RQ_COM_JAM_SIGNAL_LENGTH = 50 bytes of 0xFF) until the line is quiet.
    script = ScriptedDevice(
        [(append_crc(bytes.fromhex("09 03 02 02 00 01")), append_crc(bytes.fromhex("09 03 02 07 E8")))]
    )
    device = LeftStreaming(script)
    server = serve(device)
    bus = ModbusBus(server.url, baudrate=19200, timeout_s=0.3, retries=0, device="bus")
    gauge = FT300(bus, SystemClock())
    assert gauge.stopped_stream_at_open
    assert device.heard == b"\xff" * 50  # nothing before the jam, one jam
    assert bus.read_holding(9, 514, 1, device="gauge") == [2024]
    bus.close()
    script.check()
