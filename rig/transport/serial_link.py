"""Byte transport over a serial port URL (a device path, a pty, ``socket://host:port``).

The only module that imports pyserial. Every read has a timeout; a vanished port
becomes ``DeviceDisconnected``, an incomplete reply ``DeviceTimeout``, a port another
process holds ``DeviceBusy`` (device paths are opened exclusively: ``rig.transport.exclusive``).
Interrupted system calls are retried (``rig.transport.eintr``). On a port served by an
in-process simulator, reply timeouts follow the simulator's time (``rig.transport.peer``).
"""

from __future__ import annotations

import os
import select
import socket
import threading
from typing import Callable

import serial
from serial.urlhandler.protocol_socket import Serial as SocketPort

from rig.clock import SystemClock
from rig.errors import DeviceDisconnected, DeviceTimeout
from rig.transport import exclusive
from rig.transport import peer as peers
from rig.transport.eintr import TERMIOS_ERROR, retry_eintr

# Every way a port fails when its device vanishes: pyserial's own error, the OS's,
# termios.error from tcdrain on a dead pty (not an OSError), and TypeError from a
# port pyserial has already closed.
PORT_ERRORS = (serial.SerialException, OSError, TypeError, *TERMIOS_ERROR)

# Real seconds one blocking read waits before the reply deadline is checked again.
POLL_S = 0.01
_REAL = SystemClock()  # reply deadlines on hardware are real time
# pyserial pauses 0.3 s after closing a ``socket://`` port, "in case of quick reconnects" (a serial
# server on Ethernet may take one client at a time): every command paid it per link at its exit.
# The pause is kept only where it serves: before this process opens the same address again.
RECONNECT_PAUSE_S = 0.3
_socket_closed_at: dict[str, float] = {}  # socket:// URL -> real time this process closed it


class TrackedPort:
    """A pyserial port that counts the bytes each way and retries EINTR.

    pyserial's ``read`` and ``write`` already retry EINTR internally; ``flush``
    (tcdrain) does not, and a partial read is returned, never repeated, so only
    ``flush`` and ``in_waiting`` go through ``retry_eintr``. For ``socket://`` ports,
    ``in_waiting`` is the real byte count: pyserial's socket handler reports 0 or 1, so
    a reader that sizes its read by it fetches one byte per poll.
    Everything else is delegated to the wrapped port.
    """

    def __init__(self, port, *, exclusive_tty: bool = False, url: str = ""):
        object.__setattr__(self, "_port", port)
        object.__setattr__(self, "_url", url)
        object.__setattr__(self, "bytes_read", 0)
        object.__setattr__(self, "bytes_written", 0)
        object.__setattr__(self, "_exclusive_tty", exclusive_tty)  # TIOCEXCL set: cleared at close

    def _plain_socket(self) -> socket.socket | None:
        """The socket of a ``socket://`` port (pyserial's raw TCP handler), else None. An
        ``rfc2217://`` port has one too, but its bytes are escaped and read by pyserial's own thread."""
        return self._port._socket if isinstance(self._port, SocketPort) else None

    @property
    def in_waiting(self) -> int:
        sock = self._plain_socket()
        if sock is None:
            return retry_eintr(lambda: self._port.in_waiting)
        try:
            return len(sock.recv(65536, socket.MSG_PEEK | socket.MSG_DONTWAIT))
        except BlockingIOError:
            return 0
        except OSError as exc:
            raise serial.SerialException(f"socket failed: {exc}") from exc

    def read(self, size: int = 1) -> bytes:
        data = self._port.read(size)
        object.__setattr__(self, "bytes_read", self.bytes_read + len(data))
        return data

    def write(self, data: bytes) -> int:
        """Send all of ``data``; SerialTimeoutException only when the line stays blocked with
        bytes unsent past the write timeout.

        pyserial checks its write deadline after each successful send, so a process
        descheduled past the deadline (a loaded machine) is told "Write timeout" for bytes
        that went out. Here the deadline counts only while bytes are still waiting; ports
        without a file descriptor or socket (``loop://``) use pyserial's own write.
        """
        fd = self._raw_fd()
        if fd is None:
            n = self._port.write(data)
        else:
            n = self._send_all(fd, memoryview(bytes(data)))
        object.__setattr__(self, "bytes_written", self.bytes_written + n)
        return n

    def _raw_fd(self) -> int | None:
        sock = self._plain_socket()
        if sock is not None:
            return sock.fileno()
        if hasattr(self._port, "_socket"):
            return None  # a closed socket:// port, or rfc2217 (its writes escape 0xFF): pyserial's own write
        fd = getattr(self._port, "fd", None)
        return fd if isinstance(fd, int) else None

    def _send_all(self, fd: int, view: memoryview) -> int:
        timeout_s = self._port.write_timeout
        deadline = None if timeout_s is None else _REAL.now() + timeout_s
        sent = 0
        while sent < len(view):
            try:
                sent += os.write(fd, view[sent:])
                continue
            except (BlockingIOError, InterruptedError):
                pass  # the line is full (or a signal came): wait until it takes more
            left = None if deadline is None else deadline - _REAL.now()
            if left is not None and left <= 0:
                raise serial.SerialTimeoutException(f"Write timeout ({sent} of {len(view)} bytes sent)")
            select.select([], [fd], [], left)
        return sent

    def flush(self) -> None:
        retry_eintr(self._port.flush)

    def close(self) -> None:
        fd = getattr(self._port, "fd", None)
        if self._exclusive_tty and isinstance(fd, int):
            exclusive.let_go(fd)
        sock = self._plain_socket()
        if sock is None:
            self._port.close()
            return
        # pyserial's socket close, less its pause (RECONNECT_PAUSE_S)
        self._port.is_open = False
        self._port._socket = None
        _socket_closed_at[self._url] = _REAL.now()
        for end in (lambda: sock.shutdown(socket.SHUT_RDWR), sock.close):
            try:
                end()
            except OSError:
                pass  # the peer went first; pyserial ignores these too

    def __getattr__(self, name):
        return getattr(self._port, name)

    def __setattr__(self, name, value):
        setattr(self._port, name, value)


def open_port(url: str, *, baudrate: int, timeout_s: float, device: str) -> TrackedPort:
    """Open ``url`` with pyserial (8N1); a device path exclusively (its node flock'd, TIOCEXCL).
    Raises DeviceBusy when another process holds it, else DeviceDisconnected naming the port."""
    lock = exclusive.lockable(url)
    try:
        # A simulator in this process drains its port from a thread that a loaded machine may
        # starve: its write deadline is the real-time stall limit, like its replies'.
        peer = peers.lookup(url)
        write_timeout_s = max(timeout_s, peer.stall_limit_s) if peer is not None else timeout_s
        options = {"exclusive": True} if lock else {}
        closed_at = _socket_closed_at.pop(url, None)
        if closed_at is not None:  # closed by this process a moment ago: the pause pyserial would have made
            _REAL.sleep(closed_at + RECONNECT_PAUSE_S - _REAL.now())
        port = serial.serial_for_url(
            url, baudrate=baudrate, timeout=timeout_s, write_timeout=write_timeout_s, **options
        )
    except (*PORT_ERRORS, ValueError) as exc:
        busy = exclusive.busy_error(url, exc) if lock else None
        if busy is not None:
            raise busy from None
        errno = getattr(exc, "errno", None)  # pyserial's own text repeats the port twice
        why = os.strerror(errno) if isinstance(errno, int) else str(exc)
        port_name = "the port" if url in device else f"port {url}"  # the device's name often says which
        raise DeviceDisconnected(device, f"open {url}", None, f"cannot open {port_name}: {why}") from exc
    fd = getattr(port, "fd", None)
    return TrackedPort(port, exclusive_tty=lock and isinstance(fd, int) and exclusive.hold(fd), url=url)


class _RealTimeWait:
    """Hardware: a reply is late ``timeout_s`` real seconds after the wait began."""

    def __init__(self, timeout_s: float):
        self.timeout_s = timeout_s
        self.deadline = _REAL.now() + timeout_s

    def late(self) -> str | None:
        return f"no reply within {self.timeout_s:g} s" if _REAL.now() >= self.deadline else None


class _PeerWait:
    """In-process simulator: a reply is late when the simulator says none is coming
    within ``timeout_s`` of its time, or when it has not answered for ``stall_limit_s``
    real seconds (stalled or dead)."""

    def __init__(self, link: "SerialLink", peer):
        self.link, self.peer = link, peer
        self.started = _REAL.now()

    def late(self) -> str | None:
        link, peer = self.link, self.peer
        if not peer.alive:
            return "no reply: the simulator has stopped"
        outlook = peer.reply_outlook(link._peer_base, link.port.bytes_written, link.port.bytes_read, link.timeout_s)
        if outlook is peers.Outlook.SILENT:
            return f"no reply within {link.timeout_s:g} s (simulated time)"
        if _REAL.now() - self.started > peer.stall_limit_s:
            return (
                f"no reply within {link.timeout_s:g} s: the simulator did not answer "
                f"in {peer.stall_limit_s:g} s of real time"
            )
        return None


class SerialLink:
    """A serial port shared by the devices on it (a Zaber daisy chain, an RS-485 bus).

    ``lock`` serialises request/reply exchanges between the users of the port. Bytes
    read past the end of a reply are kept for the next read.
    """

    def __init__(self, url: str, *, baudrate: int, timeout_s: float, device: str):
        self.url = url
        self.device = device
        self.timeout_s = timeout_s
        self.port = open_port(url, baudrate=baudrate, timeout_s=POLL_S, device=device)
        self.lock = threading.RLock()
        self._rx = bytearray()
        peer = peers.lookup(url)
        self._peer_base = peer.counters() if peer is not None else (0, 0)

    def _fail(self, what: str, command: str, exc: BaseException, device: str | None) -> DeviceDisconnected:
        return DeviceDisconnected(device or self.device, command, None, f"{what} {self.url} failed: {exc}")

    def write(self, data: bytes, command: str, *, device: str | None = None) -> None:
        try:
            self.port.write(data)
            self.port.flush()
        except PORT_ERRORS as exc:
            raise self._fail("write to", command, exc, device) from exc

    def _read_some(self, command: str, device: str | None) -> bytes:
        """What arrives within one port timeout (POLL_S unless a stream changed it)."""
        try:
            first = self.port.read(1)
            if not first:
                return b""
            waiting = self.port.in_waiting
            return first + (self.port.read(waiting) if waiting else b"")
        except PORT_ERRORS as exc:
            raise self._fail("read from", command, exc, device) from exc

    def read_frame(self, frame_end: Callable[[bytes], int | None], command: str, *, device: str | None = None) -> bytes:
        """Read until ``frame_end(buffer)`` gives the length of the frame at its start;
        return that frame. DeviceTimeout (with what did arrive) when the reply is late."""
        peer = peers.lookup(self.url)
        wait = _PeerWait(self, peer) if peer is not None else _RealTimeWait(self.timeout_s)
        # An in-process simulator on a discrete clock answers in this thread (rig/sim/link.py).
        serve_now = peer.serve_now if getattr(peer, "inline", False) is True else None  # type: ignore[union-attr]
        while True:
            end = frame_end(bytes(self._rx))
            if end:
                frame = bytes(self._rx[:end])
                del self._rx[:end]
                return frame
            if serve_now is not None:
                serve_now()
            chunk = self._read_some(command, device)
            if chunk:
                self._rx += chunk
                continue
            late = wait.late()
            if late:
                partial = bytes(self._rx)
                self._rx.clear()
                raise DeviceTimeout(device or self.device, command, partial, late)

    def read_until(self, terminator: bytes, command: str) -> bytes:
        """Read through ``terminator``; raises DeviceTimeout with what did arrive."""

        def end(buf: bytes) -> int | None:
            i = buf.find(terminator)
            return i + len(terminator) if i >= 0 else None

        return self.read_frame(end, command)

    def read_exact(self, n: int, command: str) -> bytes:
        return self.read_frame(lambda buf: n if len(buf) >= n else None, command)

    def read_available(self, max_bytes: int = 65536) -> bytes:
        """Whatever has arrived (waits up to the port timeout for the first byte)."""
        if self._rx:
            data = bytes(self._rx[:max_bytes])
            del self._rx[:max_bytes]
            return data
        return self._read_some("read", None)

    def has_peer(self) -> bool:
        """True when the far end is a simulator in this process (rig/transport/peer.py), inline or not."""
        return peers.lookup(self.url) is not None

    def inline_peer(self) -> bool:
        """True when the far end is a simulator in this process that serves inline (a pty
        on a discrete clock, a non-blocking model: rig/sim/link.py ``SimServer.inline``)."""
        return getattr(peers.lookup(self.url), "inline", False) is True

    def can_wait_readable(self) -> bool:
        """True when the port has a file descriptor to wait on (``wait_readable``)."""
        return self.port._raw_fd() is not None

    def wait_readable(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` real seconds for bytes to read, taking none."""
        if self._rx:
            return True
        fd = self.port._raw_fd()
        if fd is None:  # closed under us (or a port without one: see can_wait_readable)
            raise self._fail("wait on", "read", OSError("the port has no file descriptor"), None)
        try:
            return bool(retry_eintr(lambda: select.select([fd], [], [], timeout_s)[0]))
        except (*PORT_ERRORS, ValueError) as exc:
            raise self._fail("wait on", "read", exc, None) from exc

    def in_flight(self) -> int:
        """Bytes an in-process simulator has sent that this link has not read yet: on the
        line, or still inside the kernel's pty (it hands them over asynchronously, later on
        a loaded machine). 0 on hardware, where nothing can know."""
        peer = peers.lookup(self.url)
        if peer is None:
            return 0
        return max(0, peer.counters()[1] - self._peer_base[1] - self.port.bytes_read)

    def read_waiting(self) -> bytes:
        """What has arrived, without waiting (b"" when nothing has)."""
        return self._take_all("read from", "read", None)

    def discard_input(self, *, device: str | None = None) -> bytes:
        """Drop stale bytes (a late reply to an earlier, timed-out command)."""
        return self._take_all("flush", "discard input", device)

    def _take_all(self, verb: str, what: str, device: str | None) -> bytes:
        """Everything buffered and waiting in the port, without waiting for more."""
        data = bytes(self._rx)
        self._rx.clear()
        try:
            waiting = self.port.in_waiting
            return data + (self.port.read(waiting) if waiting else b"")
        except PORT_ERRORS as exc:
            raise self._fail(verb, what, exc, device) from exc

    def close(self) -> None:
        try:
            self.port.close()
        except PORT_ERRORS:
            pass  # closing a port that already vanished is not an error worth raising
