"""Serve a simulated device's bytes on a pty or a loopback TCP socket, in a thread.

The driver under test opens the pty's path (or ``socket://127.0.0.1:PORT``) exactly
as it would open ``/dev/ttyUSB0``; pyserial and pymodbus run unchanged.
"""

from __future__ import annotations

import heapq
import itertools
import os
import pty
import select
import socket
import threading
import time
import tty
from typing import Protocol

from rig.clock import Clock
from rig.sim.faults import FaultInjector


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

    def __init__(self, model: DeviceModel, clock: Clock, *, transport: str = "pty",
                 faults: FaultInjector | None = None, name: str = "sim"):
        if transport not in ("pty", "tcp"):
            raise ValueError(f"transport must be 'pty' or 'tcp', got {transport!r}")
        self.model = model
        self.clock = clock
        self.faults = faults or FaultInjector()
        self.name = name
        self.transport = transport
        self._stop = threading.Event()
        self._pending: list[tuple[float, int, bytes]] = []  # (real send time, seq, data)
        self._seq = itertools.count()
        self._conn: socket.socket | None = None
        self._lock = threading.Lock()
        self._model_lock = threading.RLock()  # the loop thread and clock pumps share the model
        self.bytes_in = 0
        self.bytes_out = 0
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
        if hasattr(clock, "add_listener"):
            clock.add_listener(self.pump)

    # -- the loop -------------------------------------------------------------
    def _input_fd(self):
        if self.transport == "pty":
            return self._master
        return self._conn if self._conn is not None else self._listen

    def _run(self) -> None:
        while not self._stop.is_set():
            interval = self.model.tick_interval_s()
            timeout = 0.05 if interval is None else interval
            if self._pending:
                timeout = min(timeout, max(0.0, self._pending[0][0] - time.monotonic()))
            fd = self._input_fd()
            try:
                readable, _, _ = select.select([fd], [], [], timeout)
            except (OSError, ValueError):
                return  # closed under us: the device "vanished"
            if readable:
                if self.transport == "tcp" and fd is self._listen:
                    self._conn, _ = self._listen.accept()
                    self._conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                    continue
                try:
                    data = os.read(self._master, 65536) if self.transport == "pty" else self._conn.recv(65536)
                except OSError:
                    return
                if not data and self.transport == "tcp":
                    self._conn.close()
                    self._conn = None
                    continue
                self.bytes_in += len(data)
                with self._model_lock:
                    self._queue(self.model.feed(data, self.clock.now()))
            self.pump()

    def pump(self) -> None:
        """Emit what the model has due now (stream frames), under the model lock."""
        with self._model_lock:
            if self._master < 0 and self._conn is None and self.transport == "pty":
                return
            self._queue(self.model.tick(self.clock.now()))
            self._flush_due()

    def _queue(self, frames: list[bytes]) -> None:
        now = time.monotonic()
        for frame in frames:
            out, delay = self.faults.apply(frame)
            if out:
                heapq.heappush(self._pending, (now + delay, next(self._seq), out))

    def _flush_due(self) -> None:
        now = time.monotonic()
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
            self.bytes_out += len(data)
        except OSError:
            pass  # the host end went away; the next read notices

    # -- control --------------------------------------------------------------
    def disconnect(self) -> None:
        """The device vanishes: its port closes under the driver."""
        self._stop.set()
        self._close_fds()

    def close(self) -> None:
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
