"""A Modbus RTU server for simulated devices, written apart from the client.

The drivers frame requests with ``rig.transport.modbus_frames``; the simulators parse
and build frames with this separate implementation, and the exchange tests pin the
bytes to the manuals, so a test exercises two codecs against each other.
Like a real RS-485 slave (Modbus over Serial Line v1.02 §2.1, §2.4.1), a frame with a
bad CRC or for another device id gets no answer at all: on a shared line only the
addressed device may talk. (pymodbus 3.16's server answers an unknown id with exception
11, GATEWAY TARGET DEVICE FAILED TO RESPOND, unless ``ignore_missing_devices``; its
code 4 is for a datastore error. Both are gateway answers, not a serial slave's.) Device
id 0 is the broadcast address: a write is carried out by every device, and none
answers (§2.1: broadcast requests are writes; no reply).
"""

from __future__ import annotations

import struct
from typing import Protocol

from rig.sim.link import RequestReplyDevice
from rig.transport.crc import append_crc, crc_ok


class ModbusException(Exception):
    def __init__(self, code: int):
        self.code = code
        super().__init__(f"Modbus exception {code}")


ILLEGAL_FUNCTION = 1
ILLEGAL_DATA_ADDRESS = 2
ILLEGAL_DATA_VALUE = 3
SERVER_DEVICE_FAILURE = 4
BROADCAST_ID = 0


class RegisterDevice(Protocol):
    def read_registers(self, address: int, count: int, now_s: float) -> list[int]:
        """Values of ``count`` registers from ``address``; raise ModbusException."""

    def write_registers(self, address: int, values: list[int], now_s: float) -> None:
        """Store ``values`` from ``address``; raise ModbusException."""


def _request_length(buf: bytes) -> int | None:
    """Length of the request frame at the start of ``buf``, or None if unknown yet."""
    if len(buf) < 2:
        return None
    fc = buf[1]
    if fc in (3, 4, 6):
        return 8
    if fc == 16:
        return 9 + buf[6] if len(buf) >= 7 else None
    return len(buf)  # unknown function: the whole burst is one frame


class RtuServer(RequestReplyDevice):
    """Dispatches RTU frames to register devices by device id."""

    def __init__(self, devices: dict[int, RegisterDevice]):
        self.devices = devices
        self._buf = b""
        self.crc_errors = 0

    @property
    def serves_inline(self) -> bool:
        """Non-blocking (may be served in a waiting driver's thread, rig/sim/link.py) when
        every register device behind it declares so."""
        return all(getattr(d, "serves_inline", False) is True for d in self.devices.values())

    def feed(self, data: bytes, now_s: float) -> list[bytes]:
        self._buf += data
        replies: list[bytes] = []
        while True:
            n = _request_length(self._buf)
            if n is None or len(self._buf) < n:
                return replies
            frame, self._buf = self._buf[:n], self._buf[n:]
            if not crc_ok(frame):
                self.crc_errors += 1
                self._buf = b""  # resynchronise on the next burst, as silence would
                return replies
            reply = self.handle(frame[:-2], now_s)
            if reply is not None:
                replies.append(append_crc(reply))

    def handle(self, pdu: bytes, now_s: float) -> bytes | None:
        device_id, fc = pdu[0], pdu[1]
        if device_id == BROADCAST_ID:
            if fc in (6, 16):
                for other_id in list(self.devices):
                    self.handle(bytes([other_id]) + pdu[1:], now_s)  # each carries it out; replies dropped
            return None
        device = self.devices.get(device_id)
        if device is None:
            return None
        try:
            if fc in (3, 4):
                address, count = struct.unpack(">HH", pdu[2:6])
                if not 1 <= count <= 125:
                    raise ModbusException(ILLEGAL_DATA_VALUE)
                values = device.read_registers(address, count, now_s)
                return bytes([device_id, fc, 2 * count]) + struct.pack(f">{count}H", *values)
            if fc == 6:
                address, value = struct.unpack(">HH", pdu[2:6])
                device.write_registers(address, [value], now_s)
                return pdu[:6]
            if fc == 16:
                address, count, nbytes = struct.unpack(">HHB", pdu[2:7])
                if nbytes != 2 * count or len(pdu) != 7 + nbytes:
                    raise ModbusException(ILLEGAL_DATA_VALUE)
                values = list(struct.unpack(f">{count}H", pdu[7 : 7 + nbytes]))
                device.write_registers(address, values, now_s)
                return pdu[:6]
            raise ModbusException(ILLEGAL_FUNCTION)
        except ModbusException as exc:
            return bytes([device_id, fc | 0x80, exc.code])
