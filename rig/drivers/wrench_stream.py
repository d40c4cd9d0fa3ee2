"""Streaming six-axis samples: frame sync, a bounded timestamped buffer, a reader thread. The
gauge behaviour (tare, fresh reads) shared by every gauge driver is rig/drivers/gauge_base.py.
"""

from __future__ import annotations

import collections
import threading
from typing import Callable, Protocol

import numpy as np

from rig.clock import Clock
from rig.errors import DeviceError
from rig.types import Wrench

STREAM_POLL_S = 0.02  # port timeout while streaming: how quickly the reader notices a stop
DRAIN_QUIET_S = 0.05  # a stream has ended when nothing arrived for this long


def drain(port) -> int:
    """Read and drop bytes until the line has been quiet for DRAIN_QUIET_S; returns the count."""
    saved, port.timeout = port.timeout, DRAIN_QUIET_S
    try:
        n = 0
        while True:
            chunk = port.read(4096)
            if not chunk:
                return n
            n += len(chunk)
    finally:
        port.timeout = saved


class FrameSync:
    """Cuts fixed-length frames starting with ``header`` out of a byte stream.

    A frame failing ``valid`` (checksum/CRC) is counted and skipped one byte at a
    time, so one corrupted frame costs that frame only, never a wrong value.
    """

    def __init__(self, header: bytes, length: int, valid: Callable[[bytes], bool]):
        self.header = header
        self.length = length
        self.valid = valid
        self._buf = bytearray()
        self.frames_ok = 0
        self.frames_bad = 0
        self.bytes_skipped = 0

    def feed(self, data: bytes) -> list[bytes]:
        self._buf += data
        out: list[bytes] = []
        while True:
            i = self._buf.find(self.header)
            if i < 0:
                keep = len(self.header) - 1
                self.bytes_skipped += max(0, len(self._buf) - keep)
                del self._buf[: max(0, len(self._buf) - keep)]
                return out
            if i:
                self.bytes_skipped += i
                del self._buf[:i]
            if len(self._buf) < self.length:
                return out
            frame = bytes(self._buf[: self.length])
            if self.valid(frame):
                self.frames_ok += 1
                out.append(frame)
                del self._buf[: self.length]
            else:
                self.frames_bad += 1
                del self._buf[:1]


class WrenchBuffer:
    """The newest ``capacity`` samples, host-timestamped, safe across threads."""

    def __init__(self, capacity: int = 4096):
        self._samples: collections.deque[Wrench] = collections.deque(maxlen=capacity)
        self._cond = threading.Condition()
        self.total = 0

    def push(self, sample: Wrench) -> None:
        with self._cond:
            self._samples.append(sample)
            self.total += 1
            self._cond.notify_all()

    def push_many(self, samples: list[Wrench]) -> None:
        """``push`` each, with one wake-up of the waiting readers."""
        if not samples:
            return
        with self._cond:
            self._samples.extend(samples)
            self.total += len(samples)
            self._cond.notify_all()

    def latest(self) -> Wrench | None:
        with self._cond:
            return self._samples[-1] if self._samples else None

    def newest(self, n: int) -> list[Wrench]:
        """The newest ``n`` samples (fewer when the buffer holds fewer), oldest first."""
        with self._cond:
            k = min(n, len(self._samples))
            return [self._samples[i] for i in range(len(self._samples) - k, len(self._samples))]

    def since(self, t_s: float) -> list[Wrench]:
        """Samples stamped after ``t_s``, oldest first: a reader emptying the buffer between
        captures touches only what came since (``_first_after``)."""
        with self._cond:
            i = self._first_after(t_s)
            return [self._samples[k] for k in range(i, len(self._samples))]

    def _first_after(self, t_s: float) -> int:
        """Index of the first sample stamped after ``t_s`` (len when none), the lock held.
        Stamps never go back, so the scan starts at the newest end and stops at the first
        older one: a capture asks about the last moments, not all 4096."""
        i = len(self._samples)
        for s in reversed(self._samples):
            if s.t_s <= t_s:
                break
            i -= 1
        return i

    def wait_new(self, after_total: int, n: int, timeout_s: float) -> bool:
        """Block (real time, bounded) until ``n`` samples arrived after ``after_total``."""
        with self._cond:
            return self._cond.wait_for(lambda: self.total - after_total >= n, timeout=timeout_s)

    def wait_beyond(self, count: int, timeout_s: float) -> bool:
        """Block (real time, bounded) until more than ``count`` samples have been pushed in all (``total``)."""
        with self._cond:
            return self._cond.wait_for(lambda: self.total > count, timeout=timeout_s)

    def wait_after(self, t_s: float, timeout_s: float) -> bool:
        """Block (real time, bounded) until a sample stamped at or after ``t_s`` is here."""
        with self._cond:
            return self._cond.wait_for(lambda: bool(self._samples) and self._samples[-1].t_s >= t_s, timeout=timeout_s)

    def at(self, t_s: float) -> tuple[np.ndarray, float]:
        """Wrench interpolated at ``t_s`` and the distance (s) to the nearest sample."""
        with self._cond:
            if not self._samples:
                raise LookupError("no samples")
            # bisect_right: among samples stamped exactly t_s (one burst) the newest wins
            n = len(self._samples)
            i = self._first_after(t_s)
            if i == 0 or i == n:
                s = self._samples[0] if i == 0 else self._samples[-1]
                return s.as_array(), abs(s.t_s - t_s)
            a, b = self._samples[i - 1], self._samples[i]
        w = (t_s - a.t_s) / (b.t_s - a.t_s) if b.t_s > a.t_s else 0.0
        return a.as_array() * (1 - w) + b.as_array() * w, min(t_s - a.t_s, b.t_s - t_s)


class FrameCutter(Protocol):
    """Cuts checked frames out of stream chunks, counting what it refused (FrameSync, M8128's
    PacketSync, the Net F/T's RdtSync)."""

    frames_bad: int
    bytes_skipped: int

    def feed(self, data: bytes) -> list[bytes]: ...


# (wait up to a timeout for bytes to read; take what has arrived without waiting; bytes an
# in-process simulator has sent that were not read yet)
Inline = tuple[Callable[[float], bool], Callable[[], bytes], Callable[[], int]]
IN_FLIGHT_WAITS = 200  # × up to STREAM_POLL_S real: bytes on the way are waited for, ~4 s at most


class StreamReader:
    """Reads chunks in a thread, cuts frames, decodes and buffers them.

    An error in the thread (the port vanished) is kept and raised to the next caller
    of ``check``; it is never swallowed.
    """

    def __init__(
        self,
        read_chunk: Callable[[], bytes],
        sync: FrameCutter,
        decode: Callable[[bytes], np.ndarray],
        buffer: WrenchBuffer,
        clock: Clock,
        name: str,
        inline: Inline | None = None,
    ):
        """``inline``: (wait until bytes are there, up to a timeout; take what is there
        without waiting; bytes an in-process simulator sent that were not read yet). With
        it, the thread only waits for bytes and takes them under a lock, and a caller
        waiting for a sample can take them itself (``take_now``)."""
        self.read_chunk = read_chunk
        self._inline = inline
        self._take = threading.Lock()  # one taker at a time: chunks are cut and buffered in order
        self.sync = sync
        self.decode = decode
        self.buffer = buffer
        self.clock = clock
        self.error: DeviceError | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"stream-{name}", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        empty = 0  # times in a row the line was readable and had nothing to take
        while not self._stop.is_set():
            try:
                if self._inline is not None:
                    if not self._inline[0](STREAM_POLL_S):
                        empty = 0
                        continue
                    if self.take_now():
                        empty = 0
                        continue
                    empty += 1
                    if empty < 3:
                        continue  # another caller took the bytes first
                    # Readable with nothing to take: a hung-up line; the plain read says why.
                    with self._take:
                        data = self.read_chunk()
                        if data:
                            self._cut(data)
                    empty = 0  # it did not fail: the line is alive
                    continue
                data = self.read_chunk()
            except DeviceError as exc:
                self.error = exc
                return
            if data:
                self._cut(data)

    def _cut(self, data: bytes) -> None:
        t = self.clock.now()  # host time at arrival
        self.buffer.push_many([Wrench.from_array(t, self.decode(frame)) for frame in self.sync.feed(data)])

    @property
    def inline(self) -> bool:
        """True when callers can take the stream's bytes themselves (``take_now``)."""
        return self._inline is not None

    def take_in_flight(self) -> None:
        """Wait (real time, bounded) until the bytes a simulator in this process already
        sent have been taken: the kernel hands pty bytes over asynchronously."""
        if self._inline is None:
            return
        ready, _, in_flight = self._inline
        for _ in range(IN_FLIGHT_WAITS):
            self.take_now()
            if not in_flight():
                return
            ready(STREAM_POLL_S)

    def take_now(self) -> bool:
        """Take and buffer what has arrived, in the calling thread; True if anything had.

        A caller about to wait for a sample calls this first: on a simulated rig's
        discrete clock the bytes are already on the line (written when the clock moved),
        and taking them here saves handing them to this thread and back."""
        if self._inline is None:
            return False
        with self._take:
            data = self._inline[1]()
            if data:
                self._cut(data)
        return bool(data)

    def check(self) -> None:
        if self.error is not None:
            raise self.error

    def stop(self, timeout_s: float = 2.0) -> None:
        self._stop.set()
        self._thread.join(timeout=timeout_s)
