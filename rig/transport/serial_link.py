"""Byte transport over a serial port URL (a device path, a pty, ``socket://host:port``).

The only module (with ``modbus_bus``) that imports pyserial. Every read has a timeout;
a vanished port becomes ``DeviceDisconnected``, an incomplete read ``DeviceTimeout``.
"""

from __future__ import annotations

import threading

import serial

try:
    import termios

    _TERMIOS_ERROR: tuple = (termios.error,)
except ImportError:  # not POSIX
    _TERMIOS_ERROR = ()

# Every way a port fails when its device vanishes: pyserial's own error, the OS's,
# termios.error from tcdrain on a dead pty (not an OSError), and TypeError from a
# port pyserial has already closed.
PORT_ERRORS = (serial.SerialException, OSError, TypeError, *_TERMIOS_ERROR)

from rig.errors import DeviceDisconnected, DeviceTimeout


class CountingSocketPort:
    """A pyserial ``socket://`` port whose ``in_waiting`` is the real byte count.

    pyserial's socket handler reports 0 or 1, so readers that size their read by
    ``in_waiting`` (pymodbus does) fetch one byte per poll: 17 bytes take ~40 ms.
    Everything else is delegated to the wrapped port.
    """

    def __init__(self, port):
        object.__setattr__(self, "_port", port)

    @property
    def in_waiting(self) -> int:
        import socket

        sock = self._port._socket
        try:
            return len(sock.recv(65536, socket.MSG_PEEK | socket.MSG_DONTWAIT))
        except BlockingIOError:
            return 0
        except OSError as exc:
            raise serial.SerialException(f"socket failed: {exc}") from exc

    def __getattr__(self, name):
        return getattr(self._port, name)

    def __setattr__(self, name, value):
        setattr(self._port, name, value)


def with_byte_count(port):
    """Wrap ``socket://`` ports in CountingSocketPort; other ports are returned as they are."""
    return CountingSocketPort(port) if hasattr(port, "_socket") else port


def open_port(url: str, *, baudrate: int, timeout_s: float, device: str) -> serial.SerialBase:
    """Open ``url`` with pyserial (8N1). Raises DeviceDisconnected naming the device and port."""
    try:
        return with_byte_count(serial.serial_for_url(url, baudrate=baudrate, timeout=timeout_s, write_timeout=timeout_s))
    except (*PORT_ERRORS, ValueError) as exc:
        raise DeviceDisconnected(device, f"open {url}", None, f"cannot open port {url}: {exc}") from exc


class SerialLink:
    """A serial port shared by the devices on it (a Zaber daisy chain, an RS-485 bus).

    ``lock`` serialises request/reply exchanges between the users of the port.
    """

    def __init__(self, url: str, *, baudrate: int, timeout_s: float, device: str):
        self.url = url
        self.device = device
        self.timeout_s = timeout_s
        self.port = open_port(url, baudrate=baudrate, timeout_s=timeout_s, device=device)
        self.lock = threading.RLock()

    def write(self, data: bytes, command: str) -> None:
        try:
            self.port.write(data)
            self.port.flush()
        except PORT_ERRORS as exc:
            raise DeviceDisconnected(self.device, command, None, f"write to {self.url} failed: {exc}") from exc

    def read_until(self, terminator: bytes, command: str) -> bytes:
        """Read through ``terminator``; raises DeviceTimeout with what did arrive."""
        try:
            data = self.port.read_until(terminator)
        except PORT_ERRORS as exc:
            raise DeviceDisconnected(self.device, command, None, f"read from {self.url} failed: {exc}") from exc
        if not data.endswith(terminator):
            raise DeviceTimeout(self.device, command, data, f"no reply within {self.timeout_s:g} s")
        return data

    def read_exact(self, n: int, command: str) -> bytes:
        try:
            data = self.port.read(n)
        except PORT_ERRORS as exc:
            raise DeviceDisconnected(self.device, command, None, f"read from {self.url} failed: {exc}") from exc
        if len(data) != n:
            raise DeviceTimeout(self.device, command, data, f"{len(data)} of {n} bytes within {self.timeout_s:g} s")
        return data

    def read_available(self, max_bytes: int = 65536) -> bytes:
        """Whatever has arrived (waits up to the timeout for the first byte)."""
        try:
            first = self.port.read(1)
            if not first:
                return b""
            waiting = self.port.in_waiting
            return first + (self.port.read(min(waiting, max_bytes)) if waiting else b"")
        except PORT_ERRORS as exc:
            raise DeviceDisconnected(self.device, "read", None, f"read from {self.url} failed: {exc}") from exc

    def discard_input(self) -> bytes:
        """Drop stale bytes (a late reply to an earlier, timed-out command)."""
        try:
            waiting = self.port.in_waiting
            return self.port.read(waiting) if waiting else b""
        except PORT_ERRORS as exc:
            raise DeviceDisconnected(self.device, "flush", None, f"{self.url}: {exc}") from exc

    def close(self) -> None:
        try:
            self.port.close()
        except PORT_ERRORS:
            pass  # closing a port that already vanished is not an error worth raising
