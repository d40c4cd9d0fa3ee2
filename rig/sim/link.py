"""Serve a simulated device's bytes on a pty or a loopback TCP socket, in a thread.

The driver under test opens the pty's path (or ``socket://127.0.0.1:PORT``) exactly
as it would open ``/dev/ttyUSB0``; pyserial runs unchanged.

Replies leave at simulated time (a fault's delay is simulated seconds). The server
registers its URL as an in-process peer (``rig.transport.peer``) so that a driver's
reply timeout counts simulated time and cannot fire because this thread was starved
of CPU on a loaded machine. os.read/os.write/select are retried on EINTR by Python
itself (PEP 475); nothing here calls tcdrain.
"""

from __future__ import annotations

import heapq
import itertools
import os
import pty
import select
import socket
import threading
import tty
from typing import Protocol

from rig.clock import Clock, ManualClock
from rig.sim.faults import FaultInjector
from rig.transport import peer as peers

# Real seconds a simulator may take to answer a request before a driver calls it dead.
# Far beyond any CPU starvation seen (a loaded 2-core machine stalled the
# thread past 0.3 s), and still a bounded wait for a hung simulator.
STALL_LIMIT_S = 10.0


class DeviceModel(Protocol):
    """What a link needs from a simulated device."""

    def feed(self, data: bytes, now_s: float) -> list[bytes]:
        """Bytes from the host; returns the frames to send back."""

    def tick(self, now_s: float) -> list[bytes]:
        """Unsolicited output due by ``now_s`` (stream frames); usually empty."""

    def tick_interval_s(self) -> float | None:
        """Real seconds between ticks while streaming, or None when idle."""


class RequestReplyDevice:
    """Base for simulated devices that only answer requests (no unsolicited stream)."""

    def tick_interval_s(self) -> float | None:
        return None

    def tick(self, now_s: float) -> list[bytes]:
        return []


class SimServer:
    """One device model behind one pty or TCP port."""

    def __init__(
        self,
        model: DeviceModel,
        clock: Clock,
        *,
        transport: str = "pty",
        faults: FaultInjector | None = None,
        name: str = "sim",
    ):
        if transport not in ("pty", "tcp"):
            raise ValueError(f"transport must be 'pty' or 'tcp', got {transport!r}")
        self.model = model
        self.clock = clock
        self.faults = faults or FaultInjector()
        self.name = name
        self.transport = transport
        self._stop = threading.Event()
        self._pending: list[tuple[float, int, bytes, float]] = []  # (clock send time, seq, data, latency s)
        self._seq = itertools.count()
        self._conn: socket.socket | None = None
        self._lock = threading.Lock()
        self._model_lock = threading.RLock()  # the loop thread and clock pumps share the model
        self.bytes_in = 0
        self.bytes_out = 0
        self._processed_in = 0  # bytes fed to the model and answered (replies queued)
        self.stall_limit_s = STALL_LIMIT_S
        self._discrete = hasattr(clock, "add_listener")  # time moves only when advanced
        # Served inline (``serve_now``): a pty read by drivers in this process on a discrete
        # clock, and a model that declares itself non-blocking (the built-in device models:
        # pure computation on the simulated world). A wrapper that may stall or hang (a test's
        # stalling model) declares nothing, and keeps the threaded path and its bounded timeout.
        self.inline = self._discrete and transport == "pty" and getattr(model, "serves_inline", False) is True
        self._stalled = False  # an inline server's thread holds a request through a stall
        if transport == "pty":
            self._master, self._slave = pty.openpty()
            tty.setraw(self._slave)
            self.url = os.ttyname(self._slave)
            self._listen = None
        else:
            self._listen = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            self._listen.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._listen.bind(("127.0.0.1", 0))
            self._listen.listen(1)
            self.url = f"socket://127.0.0.1:{self._listen.getsockname()[1]}"
            self._master = self._slave = -1
        self._thread = threading.Thread(target=self._run, name=f"sim-{name}", daemon=True)
        self._thread.start()
        peers.register(self.url, self)
        if hasattr(clock, "add_listener"):
            clock.add_listener(self.pump)

    # -- the loop -------------------------------------------------------------
    def _input_fd(self):
        if self.transport == "pty":
            return self._master
        return self._conn if self._conn is not None else self._listen

    def _run(self) -> None:
        while not self._stop.is_set():
            # A discrete clock pumps the model on every advance (``pump``, a clock listener):
            # between advances nothing is due, so this thread only waits for the host's bytes
            # instead of waking every tick to find nothing to send.
            interval = None if self._discrete else self.model.tick_interval_s()
            timeout = 0.05 if interval is None else interval
            if self._pending and not self._discrete:
                timeout = min(timeout, self._real_s_until(self._pending[0][0]))
            fd = self._input_fd()
            try:
                readable, _, _ = select.select([fd], [], [], timeout)
            except (OSError, ValueError):
                return  # closed under us: the device "vanished"
            if not readable and self._discrete:
                continue  # nothing came and the clock stood still: nothing can be due
            if readable:
                if self.transport == "tcp" and fd is self._listen:
                    self._conn, _ = self._listen.accept()
                    self._conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                    continue
                if self.inline:
                    # A waiting driver may serve its own request (serve_now): read and answer
                    # under the model lock, so that the model sees the bytes in their order.
                    try:
                        self._serve_inline_thread()
                    except OSError:
                        return
                    continue
                conn = self._conn  # tcp: the accepted connection (the listening socket was handled above)
                try:
                    data = os.read(self._master, 65536) if conn is None else conn.recv(65536)
                except OSError:
                    return
                if not data and conn is not None:
                    conn.close()
                    self._conn = None
                    continue
                self.bytes_in += len(data)
                stall_s = self.faults.take_stall()
                if stall_s:
                    self._stop.wait(stall_s)  # a thread starved of CPU: real time, no simulated time
                with self._model_lock:
                    self._queue(self.model.feed(data, self.clock.now()))
                    self._processed_in += len(data)
            self.pump()

    def _serve_inline_thread(self) -> None:
        """This thread's turn at an inline server's pty: what the host left on the line,
        read and answered under the model lock (a driver's ``serve_now`` may have taken it
        first). An armed stall is taken here, outside the lock and with ``serve_now``
        refusing meanwhile, so the stalled request is answered after the stall, in order."""
        with self._model_lock:
            data = self._read_waiting_locked()
            if data is None:
                return
            stall_s = self.faults.take_stall()
            if not stall_s:
                self._feed_locked(data)
                return
            self._stalled = True
        try:
            self._stop.wait(stall_s)  # a thread starved of CPU: real time, no simulated time
        finally:
            with self._model_lock:
                self._stalled = False
                self._feed_locked(data)

    def _read_waiting_locked(self) -> bytes | None:
        """What the host has written to the pty, read without waiting; None when nothing is
        there or the pty is closed (the model lock held)."""
        fd = self._master
        if fd < 0 or not select.select([fd], [], [], 0)[0]:
            return None
        data = os.read(fd, 65536)
        self.bytes_in += len(data)
        return data

    def _feed_locked(self, data: bytes) -> None:
        """Feed the host's bytes to the model and send what is due (the model lock held)."""
        self._queue(self.model.feed(data, self.clock.now()))
        self._processed_in += len(data)
        self._queue(self.model.tick(self.clock.now()))
        self._flush_due()

    def serve_now(self) -> bool:
        """Take what the host has written and answer it, in the calling thread; True if
        there was something. A driver waiting for its reply on the discrete clock calls this
        (rig/transport/serial_link.py): the same bytes through the same pty, without handing
        the request to this server's thread and the reply back (two thread switches per
        exchange, each a scheduler slice on a loaded machine).

        Only for an inline server (``inline``: a pty in this process, a discrete clock, and
        a model that declares ``serves_inline``: pure computation on the simulated world,
        which cannot hang). Never while a stall is armed or being taken: a stall is this
        server's thread's, so that a stalled or dead simulator stays a bounded timeout."""
        if not self.inline or self._stalled or self.faults.stall_armed:
            return False
        with self._model_lock:
            data = None if self._stalled else self._read_waiting_locked()
            if data is None:
                return False
            self._feed_locked(data)
        return True

    def _real_s_until(self, t_clock: float) -> float:
        """Real seconds until clock time ``t_clock`` (a discrete clock is pumped on advance)."""
        if self._discrete:
            return 0.05
        return max(0.0, (t_clock - self.clock.now()) / getattr(self.clock, "factor", 1.0))

    def pump(self) -> None:
        """Emit what the model has due now (stream frames), under the model lock."""
        with self._model_lock:
            if self._master < 0 and self._conn is None and self.transport == "pty":
                return
            self._queue(self.model.tick(self.clock.now()))
            self._flush_due()

    def _queue(self, frames: list[bytes]) -> None:
        now = self.clock.now()
        for frame in frames:
            out, delay = self.faults.apply(frame)
            if out:
                heapq.heappush(self._pending, (now + delay, next(self._seq), out, delay))

    def _flush_due(self) -> None:
        now = self.clock.now()
        chunks = []
        while self._pending and self._pending[0][0] <= now:
            chunks.append(heapq.heappop(self._pending)[2])
        if not chunks:
            return
        data = b"".join(chunks)
        try:
            if self.transport == "pty":
                os.write(self._master, data)
            elif self._conn is not None:
                self._conn.sendall(data)
            else:
                return  # no host connected: the bytes are lost, not sent
            self.bytes_out += len(data)
        except OSError:
            pass  # the host end went away; the next read notices

    # -- the in-process peer (rig.transport.peer) ------------------------------
    @property
    def alive(self) -> bool:
        return self._thread.is_alive() and not self._stop.is_set()

    def counters(self) -> tuple[int, int]:
        return self._processed_in, self.bytes_out

    def reply_outlook(self, base: tuple[int, int], written: int, read: int, timeout_s: float) -> peers.Outlook:
        # Never wait for the model lock: a simulator stuck in a model call is "reading",
        # and the driver's stall limit (real time) decides when it is dead.
        if not self._model_lock.acquire(timeout=0.01):
            return peers.Outlook.READING
        try:
            if self._processed_in - base[0] < written:
                return peers.Outlook.READING
            if self.bytes_out - base[1] > read:
                return peers.Outlook.COMING  # on the wire, not read yet
            in_time = [due for due, _, _, latency in self._pending if latency <= timeout_s]
            now = self.clock.now()
        finally:
            self._model_lock.release()
        if in_time:
            if isinstance(self.clock, ManualClock) and min(in_time) > now:
                self.clock.advance(min(in_time) - now)  # emits it, through pump
            return peers.Outlook.COMING
        if isinstance(self.clock, ManualClock):
            self.clock.advance(timeout_s)  # waiting out a device timeout takes simulated time
        return peers.Outlook.SILENT

    # -- control --------------------------------------------------------------
    def disconnect(self) -> None:
        """The device vanishes: its port closes under the driver."""
        peers.unregister(self.url, self)
        self._stop.set()
        self._close_fds()

    def close(self) -> None:
        peers.unregister(self.url, self)
        self._stop.set()
        self._thread.join(timeout=1.0)
        self._close_fds()

    def _close_fds(self) -> None:
        with self._lock:
            for fd in (self._master, self._slave):
                if fd >= 0:
                    try:
                        os.close(fd)
                    except OSError:
                        pass
            self._master = self._slave = -1
            for s in (self._conn, self._listen):
                if s is not None:
                    try:
                        s.close()
                    except OSError:
                        pass
            self._conn = self._listen = None
