"""A Modbus RTU bus (RS-485 line or ``socket://`` RTU-over-TCP) through pymodbus.

The only module that imports pymodbus. Exception responses become ``DeviceRejected``
with the Modbus exception name; no reply after the retries becomes ``DeviceTimeout``;
a vanished port ``DeviceDisconnected``. Several drives share one bus by device id.
"""

from __future__ import annotations

import logging
import threading

from pymodbus.client import ModbusSerialClient
from pymodbus.exceptions import ConnectionException, ModbusIOException

from rig.errors import DeviceDisconnected, DeviceRejected, DeviceTimeout
from rig.transport.serial_link import PORT_ERRORS, with_byte_count

# Modbus application exception codes (Modbus Application Protocol v1.1b3, §7).
EXCEPTION_NAMES = {
    1: "ILLEGAL FUNCTION",
    2: "ILLEGAL DATA ADDRESS",
    3: "ILLEGAL DATA VALUE",
    4: "SERVER DEVICE FAILURE",
    5: "ACKNOWLEDGE",
    6: "SERVER DEVICE BUSY",
    8: "MEMORY PARITY ERROR",
    10: "GATEWAY PATH UNAVAILABLE",
    11: "GATEWAY TARGET DEVICE FAILED TO RESPOND",
}

# pymodbus logs every timeout at ERROR before raising; we raise a typed error that
# says the same thing with the device name, so keep its logger quieter.
logging.getLogger("pymodbus").setLevel(logging.CRITICAL)


def to_signed16(value: int) -> int:
    return value - 0x10000 if value & 0x8000 else value


def to_unsigned16(value: int) -> int:
    if not -0x8000 <= value <= 0xFFFF:
        raise ValueError(f"{value} does not fit a 16-bit register")
    return value & 0xFFFF


def split_int32(value: int) -> list[int]:
    """Signed 32-bit value as two registers, high word first."""
    if not -(2**31) <= value < 2**31:
        raise ValueError(f"{value} does not fit a signed 32-bit register pair")
    v = value & 0xFFFFFFFF
    return [v >> 16, v & 0xFFFF]


def join_int32(high: int, low: int) -> int:
    v = (high << 16) | low
    return v - 2**32 if v & 0x80000000 else v


class ModbusBus:
    """One Modbus RTU line; methods take the device id of the drive or gauge on it."""

    def __init__(self, url: str, *, baudrate: int, timeout_s: float, retries: int, device: str):
        self.url = url
        self.device = device
        self.lock = threading.RLock()
        self.client = ModbusSerialClient(url, baudrate=baudrate, timeout=timeout_s, retries=retries)
        if not self.client.connect():
            raise DeviceDisconnected(device, f"open {url}", None, f"cannot open Modbus port {url}")
        self.client.socket = with_byte_count(self.client.socket)

    def _call(self, what: str, device: str, fn, *args, **kwargs):
        with self.lock:
            try:
                reply = fn(*args, **kwargs)
            except ModbusIOException as exc:
                raise DeviceTimeout(device, what, None, f"no valid Modbus reply on {self.url}: {exc}") from exc
            except ConnectionException as exc:
                raise DeviceDisconnected(device, what, None, f"Modbus port {self.url} lost: {exc}") from exc
            except PORT_ERRORS as exc:
                raise DeviceDisconnected(device, what, None, f"Modbus port {self.url} failed: {exc}") from exc
        if reply is None:
            raise DeviceTimeout(device, what, None, f"no reply on {self.url}")
        if reply.isError():
            code = getattr(reply, "exception_code", None)
            name = EXCEPTION_NAMES.get(code, f"exception {code}")
            raise DeviceRejected(device, what, f"exception response, code {code}", f"Modbus exception {code} ({name})")
        return reply

    def read_holding(self, device_id: int, address: int, count: int, *, device: str) -> list[int]:
        what = f"read holding {address:#06x} x{count} @id {device_id}"
        reply = self._call(what, device, self.client.read_holding_registers, address, count=count, device_id=device_id)
        return list(reply.registers)

    def read_input(self, device_id: int, address: int, count: int, *, device: str) -> list[int]:
        what = f"read input {address:#06x} x{count} @id {device_id}"
        reply = self._call(what, device, self.client.read_input_registers, address, count=count, device_id=device_id)
        return list(reply.registers)

    def write_register(self, device_id: int, address: int, value: int, *, device: str) -> None:
        what = f"write {address:#06x}={value:#06x} @id {device_id}"
        self._call(what, device, self.client.write_register, address, to_unsigned16(value), device_id=device_id)

    def write_registers(self, device_id: int, address: int, values: list[int], *, device: str) -> None:
        what = f"write {address:#06x}={[hex(v) for v in values]} @id {device_id}"
        regs = [to_unsigned16(v) for v in values]
        self._call(what, device, self.client.write_registers, address, regs, device_id=device_id)

    def raw_port(self):
        """The underlying pyserial port, for devices that leave Modbus for a binary stream
        (the FT300's stream mode). Hold ``lock`` while using it."""
        if self.client.socket is None:
            raise DeviceDisconnected(self.device, "raw", None, f"Modbus port {self.url} is closed")
        return self.client.socket

    def close(self) -> None:
        self.client.close()
