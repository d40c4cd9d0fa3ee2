"""Modbus RTU request and reply frames for the client (host) side.

Framing and checking live here as a pair of pure functions, so the exchange
tables in the tests can state each byte. Frame layout: Modbus over Serial Line
v1.02 §2.5.1 (address, function, data, CRC-16 low byte first); replies:
Modbus Application Protocol v1.1b3 §6.3/6.4 (read: byte count then registers),
§6.6 (write single: echo of the request), §6.12 (write multiple: echo of address
and quantity), §7 (exception: function | 0x80, one exception code).
"""

from __future__ import annotations

import struct

from rig.transport.crc import append_crc, crc_ok

READ_HOLDING = 3
READ_INPUT = 4
WRITE_SINGLE = 6
WRITE_MULTIPLE = 16


class BadFrame(Exception):
    """Not a frame at all (bad CRC, unknown function): line noise or a garbled reply."""


class OtherReply(Exception):
    """A sound frame that answers some other request (another device, function,
    register or quantity): typically a late reply to an earlier, timed-out request."""


class ExceptionReply(Exception):
    """The addressed device answered this request with a Modbus exception."""

    def __init__(self, code: int):
        self.code = code
        super().__init__(f"exception code {code}")


def read_request(device_id: int, function: int, address: int, count: int) -> bytes:
    return append_crc(struct.pack(">BBHH", device_id, function, address, count))


def write_single_request(device_id: int, address: int, value: int) -> bytes:
    return append_crc(struct.pack(">BBHH", device_id, WRITE_SINGLE, address, value))


def write_multiple_request(device_id: int, address: int, values: list[int]) -> bytes:
    head = struct.pack(">BBHHB", device_id, WRITE_MULTIPLE, address, len(values), 2 * len(values))
    return append_crc(head + struct.pack(f">{len(values)}H", *values))


def reply_length(buf: bytes) -> int | None:
    """Length of the reply frame at the start of ``buf``; None until enough has arrived
    to know and to hold it. Raises BadFrame for a function no request of ours uses."""
    if len(buf) < 2:
        return None
    function = buf[1]
    if function & 0x80:
        n = 5  # id, function | 0x80, exception code, CRC
    elif function in (READ_HOLDING, READ_INPUT):
        if len(buf) < 3:
            return None
        n = 5 + buf[2]  # id, function, byte count, data, CRC
    elif function in (WRITE_SINGLE, WRITE_MULTIPLE):
        n = 8  # id, function, address, value or quantity, CRC
    else:
        raise BadFrame(f"unknown function code {function}")
    return n if len(buf) >= n else None


def parse_reply(request: bytes, reply: bytes) -> list[int] | None:
    """The registers a read returned, or None for a write, once ``reply`` is known to
    answer ``request``: CRC, device id, function, byte count, and for writes the
    echoed address and value or quantity. Raises BadFrame, OtherReply or ExceptionReply."""
    if not crc_ok(reply):
        raise BadFrame("bad CRC")
    device_id, function = request[0], request[1]
    if reply[0] != device_id:
        raise OtherReply(f"device id {reply[0]} instead of {device_id}")
    if reply[1] == function | 0x80:
        raise ExceptionReply(reply[2])
    if reply[1] != function:
        raise OtherReply(f"function {reply[1]} instead of {function}")
    if function in (READ_HOLDING, READ_INPUT):
        count = struct.unpack(">H", request[4:6])[0]
        if reply[2] != 2 * count:
            raise OtherReply(f"{reply[2]} data bytes instead of {2 * count}")
        return list(struct.unpack(f">{count}H", reply[3 : 3 + 2 * count]))
    if function == WRITE_SINGLE and reply[2:6] != request[2:6]:
        raise OtherReply(f"echo of register/value {reply[2:6].hex(' ')} instead of {request[2:6].hex(' ')}")
    if function == WRITE_MULTIPLE and reply[2:6] != request[2:6]:
        raise OtherReply(f"echo of address/quantity {reply[2:6].hex(' ')} instead of {request[2:6].hex(' ')}")
    return None
