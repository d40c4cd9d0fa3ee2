"""The real drivers write exactly the bytes the manuals describe (scripted device on a pty)."""

import numpy as np
import pytest

from rig.clock import SystemClock
from rig.drivers import zaber_ascii as za
from rig.drivers.ft300 import FT300
from rig.drivers.pr_drive import PrDriveAxis
from rig.drivers.zaber import ZaberAxis, ZaberChain
from rig.sim.scripted import ScriptedDevice
from rig.transport.crc import append_crc
from rig.transport.modbus_bus import ModbusBus
from rig.transport.serial_link import SerialLink


def zaber_reply(body: str) -> bytes:
    return f"@{body}:{za.checksum(body)}\r\n".encode()


def test_zaber_move_writes_speed_then_absolute_target(serve):
    us = 0.047625e-3
    script = ScriptedDevice([
        (za.format_command(1, 1, "set maxspeed 34402", 0, True), zaber_reply("01 1 00 OK IDLE -- 0")),
        (za.format_command(1, 1, "move abs 20997", 1, True), zaber_reply("01 1 01 OK BUSY -- 0")),
        (za.format_command(1, 1, "get pos", 2, True), zaber_reply("01 1 02 OK BUSY -- 10000")),
    ])
    server = serve(script)
    chain = ZaberChain(SerialLink(server.url, baudrate=115200, timeout_s=0.3, device="chain"))
    axis = ZaberAxis(chain, name="x", device=1, scale=us, offset=0.0)
    # 1 mm = 20997.375 microsteps -> 20997; 1 mm/s × 1.6384 speed units per microstep/s = 34401.9 -> 34402
    axis.move_to(1.0, 1.0)
    assert axis.position() == pytest.approx(10000 * us)
    chain.close()
    script.check()


def test_pr_drive_move_is_one_block_write_then_trigger(serve):
    # Path 0: absolute, target 12500 pulses (5 deg at 4 deg/rev, 10000 pulses/rev), 75 rpm, 100 ms ramps.
    block = append_crc(bytes.fromhex("01 10 62 00 00 06 0C 00 01 00 00 30 D4 00 4B 00 64 00 64"))
    trigger = append_crc(bytes.fromhex("01 06 60 02 00 10"))
    script = ScriptedDevice([
        (block, append_crc(bytes.fromhex("01 10 62 00 00 06"))),
        (trigger, trigger),
        (append_crc(bytes.fromhex("01 03 60 2A 00 02")), append_crc(bytes.fromhex("01 03 04 00 00 30 D4"))),
    ])
    server = serve(script)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=0, device="bus")
    axis = PrDriveAxis(bus, name="theta", device_id=1, pulses_per_rev=10000, travel_per_rev=4.0, unit="deg")
    axis.move_to(5.0, 5.0)
    assert axis.position() == pytest.approx(5.0)
    bus.close()
    script.check()


def test_ft300_poll_and_stream_start_bytes(serve):
    script = ScriptedDevice([
        # Read 6 registers from 180 (0xB4) of device 9: Fx 1.00 N, Fy -2.50 N, Fz 12.34 N, Mz 1 N·mm.
        (append_crc(bytes.fromhex("09 03 00 B4 00 06")),
         append_crc(bytes.fromhex("09 03 0C 00 64 FF 06 04 D2 00 7B FF CE 00 01"))),
        # The manual's start-stream request, byte for byte.
        (bytes.fromhex("09 10 01 9A 00 01 02 02 00 CD CA"), append_crc(bytes.fromhex("09 10 01 9A 00 01"))),
    ])
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
    script = ScriptedDevice([
        (bytes.fromhex("09 10 01 9A 00 01 02 02 00 CD CA"), append_crc(bytes.fromhex("09 10 01 9A 00 01"))),
        (b"\xff" * 50, b""),
    ])
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
    script = ScriptedDevice([
        (append_crc(bytes.fromhex("09 04 00 B4 00 02")), append_crc(bytes.fromhex("09 04 04 FF FF 00 02"))),
        (write, write),
    ])
    server = serve(script)
    bus = ModbusBus(server.url, baudrate=38400, timeout_s=0.3, retries=0, device="bus")
    assert bus.read_input(9, 0xB4, 2, device="gauge") == [0xFFFF, 0x0002]
    bus.write_register(1, 0x6002, 0x0040, device="drive")
    bus.close()
    script.check()
