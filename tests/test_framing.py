"""Byte-exact framing, checksums, scaling and sign, from frames worked out of the manuals."""

import struct

import numpy as np
import pytest

from rig.drivers import ft300, m8128
from rig.drivers import zaber_ascii as za
from rig.transport.crc import append_crc, crc16_modbus, crc_ok
from rig.transport.modbus_bus import join_int32, split_int32


@pytest.mark.parametrize(
    "frame, crc",
    [
        # Modbus over Serial Line spec / countless manuals: read 10 holding registers from 1.
        (bytes.fromhex("01 03 00 00 00 0A"), bytes.fromhex("C5 CD")),
        (bytes.fromhex("01 03 00 00 00 01"), bytes.fromhex("84 0A")),
        # Robotiq FT300 manual: start stream = write 0x0200 to register 410 (0x019A) of id 9.
        (bytes.fromhex("09 10 01 9A 00 01 02 02 00"), bytes.fromhex("CD CA")),
    ],
)
def test_crc16_modbus_matches_manual_frames(frame, crc):
    assert append_crc(frame)[-2:] == crc
    assert crc_ok(frame + crc)
    assert not crc_ok(frame + bytes([crc[0] ^ 1, crc[1]]))


def test_crc_check_value():
    # CRC-16/MODBUS catalogue check value for "123456789".
    assert crc16_modbus(b"123456789") == 0x4B37


def test_int32_register_pairs_high_word_first_and_signed():
    assert split_int32(36283) == [0x0000, 0x8DBB]
    assert split_int32(-1) == [0xFFFF, 0xFFFF]
    assert join_int32(0xFFFF, 0xFF38) == -200
    for v in (0, 1, -1, 2**31 - 1, -(2**31), 123456789):
        assert join_int32(*split_int32(v)) == v
    with pytest.raises(ValueError):
        split_int32(2**31)


def test_ft300_stream_frame_scaling_and_sign():
    # Fx = 1.00 N, Fy = -2.50 N, Fz = 12.34 N, Mx = 0.123 N·m, My = -0.050 N·m, Mz = 0.001 N·m
    counts = (100, -250, 1234, 123, -50, 1)
    frame = append_crc(b"\x20\x4e" + struct.pack("<6h", *counts))
    assert len(frame) == 16
    values = ft300.decode_stream_frame(frame)
    np.testing.assert_allclose(values, [1.0, -2.5, 12.34, 123.0, -50.0, 1.0])  # N and N·mm
    assert ft300.encode_stream_frame(values) == frame


def test_ft300_polled_counts_are_signed_registers():
    regs = [0x0064, 0xFF06, 0x04D2, 0x007B, 0xFFCE, 0x0001]
    from rig.transport.modbus_bus import to_signed16

    np.testing.assert_allclose(
        ft300.decode_counts([to_signed16(r) for r in regs]), [1.0, -2.5, 12.34, 123.0, -50.0, 1.0]
    )


def test_m8128_frame_layout_and_sum_byte():
    values = np.array([1.5, -2.0, 10.0, 0.25, -0.5, 0.125])  # N and N·m on the wire
    data = struct.pack("<6f", *values)
    frame = b"\xaa\x55" + (27).to_bytes(2, "big") + (7).to_bytes(2, "big") + data + bytes([sum(data) & 0xFF])
    assert len(frame) == m8128.FRAME_LENGTH == 31
    assert m8128.frame_valid(frame)
    np.testing.assert_allclose(m8128.decode_frame(frame), [1.5, -2.0, 10.0, 250.0, -500.0, 125.0])
    assert m8128.encode_frame(m8128.decode_frame(frame), 7) == frame
    bad = frame[:-1] + bytes([(frame[-1] + 1) & 0xFF])
    assert not m8128.frame_valid(bad)


def test_zaber_command_format_from_manual():
    assert za.format_command(1, 1, "move abs 36283") == b"/1 1 move abs 36283\n"
    assert za.format_command(1, 1, "get pos", message_id=12) == b"/1 1 12 get pos\n"
    assert za.format_command(1, 0, "home") == b"/1 0 home\n"


def test_zaber_checksum_is_twos_complement_of_byte_sum():
    body = "1 1 12 get pos"
    expected = (256 - sum(body.encode()) % 256) % 256
    assert za.format_command(1, 1, "get pos", 12, with_checksum=True) == f"/{body}:{expected:02X}\n".encode()


def test_zaber_reply_parsing_from_manual():
    r = za.parse_reply(b"@01 1 OK IDLE -- 36283\r\n")
    assert (r.device, r.axis, r.message_id, r.flag, r.status, r.warning, r.data) == (
        1,
        1,
        None,
        "OK",
        "IDLE",
        "--",
        "36283",
    )
    r = za.parse_reply(b"@02 1 07 RJ BUSY WR BADDATA\r\n")
    assert (r.device, r.message_id, r.flag, r.busy, r.warning, r.data) == (2, 7, "RJ", True, "WR", "BADDATA")


def test_zaber_reply_checksum_verified():
    body = "01 1 07 OK IDLE -- 100"
    good = f"@{body}:{za.checksum(body)}\r\n".encode()
    assert za.parse_reply(good).data == "100"
    with pytest.raises(za.ReplyParseError):
        za.parse_reply(good.replace(b"100", b"101"))
    with pytest.raises(za.ReplyParseError):
        za.parse_reply(b"@01 1 OK IDL -- 0\r\n")
