"""SRI M8128 against SRI's M8128 manual: byte-exact exchanges and frames.

Source: the M8128 manual's "GSD" command section (frame layout, PackageLength,
PackageNo 0..65535 wrapping, SUM over the Data part only) with its worked example
(``AT+DCKMD=SUM`` → ``ACK+DCKMD=SUM$OK``, then ``AT+GOD`` → one 31-byte frame whose
bytes and decoded values the manual lists), and its "Step 1: SMPF, Step 2: GOD or
GSD" procedure. Facts the manual does not show are listed as assumed in
docs/hardware.md ("SRI M8128: sources").
"""

import struct

import numpy as np
import pytest

from rig.clock import SystemClock
from rig.drivers import m8128 as m8
from rig.drivers.m8128 import M8128
from rig.errors import FramingError
from rig.sim.contact import SpringContact
from rig.sim.m8128_sim import M8128Sim
from rig.sim.scripted import ScriptedDevice
from rig.sim.world import SimWorld
from rig.transport.serial_link import SerialLink

# The manual's AT+GOD reply, byte for byte.
MANUAL_FRAME = bytes.fromhex(
    "AA 55 00 1B C4 C7 01 6A F4 C0 EF 7D 33 C0 49 62 C9 C0 A2 5C C6 BD A6 19 8F BD AF DA 69 3E 6E"
)
# The manual's decoded channels: forces (N), then moments (N·m).
MANUAL_VALUES = [-7.637940, -2.804561, -6.293248, -0.096856, -0.069873, 0.228373]


def test_manual_frame_layout_sum_and_values():
    assert len(MANUAL_FRAME) == m8.FRAME_LENGTH == 31
    assert int.from_bytes(MANUAL_FRAME[2:4], "big") == m8.PAYLOAD_LENGTH == 2 + 6 * 4 * 1 + 1
    assert m8.packet_number(MANUAL_FRAME) == 50375
    assert sum(MANUAL_FRAME[6:30]) & 0xFF == 0x6E == MANUAL_FRAME[30]  # SUM over Data only
    assert m8.frame_valid(MANUAL_FRAME)
    expected = np.array(MANUAL_VALUES) * [1, 1, 1, 1000, 1000, 1000]  # N·m → N·mm
    np.testing.assert_allclose(m8.decode_frame(MANUAL_FRAME), expected, atol=1e-3)
    assert m8.encode_frame(m8.decode_frame(MANUAL_FRAME), 50375) == MANUAL_FRAME


def test_sum_over_header_or_length_would_not_match_the_manual():
    # The manual's 0x6E is the sum of the Data part; over anything wider it differs.
    assert sum(MANUAL_FRAME[2:30]) & 0xFF != 0x6E
    assert sum(MANUAL_FRAME[4:30]) & 0xFF != 0x6E


def test_nan_frame_is_never_a_value():
    data = struct.pack("<6f", 1.0, float("nan"), 0, 0, 0, 0)
    frame = m8.FRAME_HEADER + struct.pack(">HH", 27, 1) + data + bytes([sum(data) & 0xFF])
    assert not m8.frame_valid(frame)


@pytest.fixture
def scripted(serve):
    def make(exchanges):
        device = ScriptedDevice(exchanges)
        server = serve(device, SystemClock())
        return device, M8128(SerialLink(server.url, baudrate=115200, timeout_s=0.3, device="m8128"), SystemClock())

    return make


def test_configure_and_god_byte_exact(scripted):
    device, g = scripted(
        [
            (b"AT+SMPF=100\r\n", b"ACK+SMPF=100$OK\r\n"),
            (b"AT+DCKMD=SUM\r\n", b"ACK+DCKMD=SUM$OK\r\n"),  # the manual's example reply
            (b"AT+GOD\r\n", MANUAL_FRAME),
        ]
    )
    g.configure()
    w = g.read()
    np.testing.assert_allclose(w.as_array(), np.array(MANUAL_VALUES) * [1, 1, 1, 1000, 1000, 1000], atol=1e-3)
    device.check()
    g.close()


def test_god_nan_reply_is_refused(scripted):
    data = struct.pack("<6f", float("inf"), 0, 0, 0, 0, 0)
    bad = m8.FRAME_HEADER + struct.pack(">HH", 27, 3) + data + bytes([sum(data) & 0xFF])
    device, g = scripted([(b"AT+GOD\r\n", bad)])
    with pytest.raises(FramingError, match="non-finite"):
        g.read()
    device.check()
    g.close()


def test_packet_numbers_from_zero_and_wrapping():
    world = SimWorld(SystemClock(), contact=SpringContact())
    sim = M8128Sim(world)
    assert m8.packet_number(sim.feed(b"AT+GOD\r\n", 0.0)[0]) == 0  # "from 0 to 65535"
    sim.packet = 65535
    frames = sim.feed(b"AT+GOD\r\nAT+GOD\r\n", 0.0)
    assert [m8.packet_number(f) for f in frames] == [65535, 0]


def test_packet_gaps_counted_repeats_dropped():
    sync = m8.PacketSync()
    frames = [m8.encode_frame(np.zeros(6), n) for n in (65534, 65535, 2, 2, 1)]
    assert len(sync.feed(b"".join(frames))) == 3
    assert (sync.lost, sync.out_of_order) == (2, 2)  # 0 and 1 lost across the wrap; 2 repeated, 1 late
    assert len(sync.feed(m8.encode_frame(np.zeros(6), 40000))) == 1 and sync.resyncs == 1


def test_sim_answers_the_rate_query(serve):
    world = SimWorld(SystemClock(), contact=SpringContact())
    server = serve(M8128Sim(world), world.clock)
    g = M8128(SerialLink(server.url, baudrate=115200, timeout_s=0.3, device="m8128"), world.clock, rate_hz=500)
    g.configure()
    assert g.command("AT+SMPF=?") == "ACK+SMPF=500$OK"
    g.close()


def test_stream_drops_counted_as_lost_packets(serve):
    world = SimWorld(SystemClock(), contact=SpringContact())
    server = serve(M8128Sim(world, rate_hz=500.0), world.clock)
    g = M8128(SerialLink(server.url, baudrate=115200, timeout_s=0.3, device="m8128"), world.clock, rate_hz=500)
    g.configure()
    g.start_stream()
    assert g.buffer.wait_new(g.buffer.total, 5, timeout_s=2.0)
    server.faults.drop_next(4)
    assert g.buffer.wait_new(g.buffer.total, 20, timeout_s=3.0)
    assert g.stream_stats()["lost"] == 4
    g.close()
