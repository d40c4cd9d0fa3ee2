"""Streaming six-axis samples: frame sync, a bounded timestamped buffer, a reader thread,
and the gauge behaviour (tare, fresh reads) shared by every gauge driver.
"""

from __future__ import annotations

import collections
import threading
from typing import Any, Callable, Protocol

import numpy as np

from rig.clock import Clock
from rig.errors import DeviceError, DeviceTimeout
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


class GaugeBase:
    """Tare and fresh reads for a gauge that can poll and stream.

    Subclasses provide ``_poll_raw`` (one untared sample), ``_stream_open`` (start
    streaming, return a chunk reader), ``_stream_close``, ``sync`` and ``decode``.
    """

    name: str
    label: str

    def __init__(self, clock: Clock, buffer_size: int = 4096, stale_after_s: float = 0.5, fresh_after_s: float = 0.05):
        self.clock = clock
        self.fresh_after_s = fresh_after_s  # bound on measurement-to-arrival latency
        self.bias = np.zeros(6)
        self.buffer = WrenchBuffer(buffer_size)
        self.stale_after_s = stale_after_s
        self._reader: StreamReader | None = None

    # -- what each driver provides -----------------------------------------------------
    def _poll_raw(self) -> np.ndarray:
        """One untared (6,) sample, polled now (N, N·mm)."""
        raise NotImplementedError

    def _stream_open(self) -> Callable[[], bytes]:
        """Start streaming; returns a reader of the next chunk (b"" when none came in time)."""
        raise NotImplementedError

    def _stream_close(self) -> None:
        """Stop streaming and drop what is still in flight."""
        raise NotImplementedError

    def _stream_inline(self) -> Inline | None:
        """(wait for bytes, take what arrived, bytes in flight) of the open stream, for
        ``StreamReader``'s ``inline``; None: the reader thread alone reads (the default)."""
        return None

    def make_sync(self) -> FrameCutter:
        raise NotImplementedError

    def decode(self, frame: bytes) -> np.ndarray:
        """One checked frame to a (6,) untared sample (N, N·mm)."""
        raise NotImplementedError

    @property
    def streaming(self) -> bool:
        return self._reader is not None

    def start_stream(self) -> None:
        if self._reader is None:
            read_chunk = self._stream_open()
            self._reader = StreamReader(
                read_chunk, self.make_sync(), self.decode, self.buffer, self.clock, self.name, self._stream_inline()
            )

    def stop_stream(self) -> None:
        if self._reader is not None:
            reader, self._reader = self._reader, None
            reader.stop()
            self._stream_close()

    def stream_stats(self) -> dict[str, Any]:
        sync = self._reader.sync if self._reader else None
        return {
            "samples": self.buffer.total,
            "frames_bad": sync.frames_bad if sync else 0,
            "bytes_skipped": sync.bytes_skipped if sync else 0,
        }

    AWAIT_TRIES = 200  # × (25 ms waiting + a 10 ms clock step): ~7 s before a timeout

    def _await(self, wait, what: str) -> None:
        """Wait for stream data: briefly in real time, then let the clock move on 10 ms.

        On hardware that is only a longer wait. On a simulated discrete-event clock,
        time moves only when someone sleeps, and the next sample is due only then.
        """
        # On a discrete-event clock with the stream taken inline, what has arrived is in the
        # buffer once take_now returns, and nothing more can arrive until the clock moves:
        # waiting in real time would only lose time, and on a loaded machine make the number
        # of clock steps (and so the simulated run) depend on the machine's load.
        reader = self._reader
        discrete = reader is not None and reader.inline and hasattr(self.clock, "add_listener")
        for _ in range(self.AWAIT_TRIES):
            if reader is not None:
                if discrete:
                    reader.take_in_flight()
                else:
                    reader.take_now()
            if wait(0.0 if discrete else 0.025):
                return
            if self._reader is not None:
                self._reader.check()
            self.clock.sleep(0.01)
        raise DeviceTimeout(self.label, what, None, "no stream sample arrived")

    def _raw_sample(self) -> Wrench:
        if self._reader is None:
            return Wrench.from_array(self.clock.now(), self._poll_raw())
        self._reader.check()
        if self._reader.inline and hasattr(self.clock, "add_listener"):
            # A simulated rig on discrete time: what its gauge sent up to this instant is on the
            # line; take it now, so that the newest sample is this instant's whatever the
            # reader thread's scheduling (the guard's checks are then the same on every run).
            self._reader.take_in_flight()
        sample = self.buffer.latest()
        now = self.clock.now()
        if sample is None or now - sample.t_s > self.stale_after_s:
            # A sample fresh at ``now``: one that arrived between the check above and this
            # wait counts (waiting for one more than the count would step the clock for nothing).
            fresh = now - self.stale_after_s
            self._await(lambda timeout: self.buffer.wait_after(fresh, timeout), "stream")
            sample = self.buffer.latest()
            assert sample is not None  # _await returns only once a sample has arrived
        return sample

    def read(self) -> Wrench:
        return self._raw_sample().minus(self.bias)

    def read_fresh(self) -> Wrench:
        """A sample measured after this call.

        A sample is stamped when it arrives; it was measured up to ``fresh_after_s``
        earlier (USB latency timers, a simulator's physics). The first sample that
        arrives that long after the call was measured after it.
        """
        if self._reader is None:
            return self.read()
        t = self.clock.now() + self.fresh_after_s
        self._await(lambda timeout: self.buffer.wait_after(t, timeout), "stream")
        sample = self.buffer.latest()
        assert sample is not None  # _await returns only once a sample stamped after t has arrived
        return sample.minus(self.bias)

    def sample_at(self, t_s: float, timeout_s: float = 2.0) -> tuple[np.ndarray, float]:
        """The tared wrench interpolated at ``t_s`` and the skew (s) to the nearest sample.

        Waits (bounded) until a sample stamped at or after ``t_s`` has arrived, so the
        interpolation brackets the moment (host arrival stamps, as published rigs do;
        the measurement-to-arrival latency is not subtracted). Polled gauges read once, now.
        """
        if self._reader is None:
            w = self.read()
            return w.as_array(), abs(w.t_s - t_s)
        self._await(lambda timeout: self.buffer.wait_after(t_s, timeout), f"sample at t = {t_s:.3f} s")
        values, skew = self.buffer.at(t_s)
        return values - self.bias, skew

    def read_raw(self) -> Wrench:
        return self._raw_sample()

    def tare(self, n_samples: int = 20) -> np.ndarray:
        """Average ``n_samples`` fresh samples and subtract them from later reads."""
        if self._reader is None:
            samples = [self._poll_raw() for _ in range(n_samples)]
        else:
            before = self.buffer.total
            for k in range(1, n_samples + 1):  # each sample within _await's budget: a slow gauge takes its time
                self._await(lambda timeout, k=k: self.buffer.wait_new(before, k, timeout_s=timeout), "tare")
            samples = [s.as_array() for s in self.buffer.since(float("-inf"))[-n_samples:]]
        self.bias = np.mean(samples, axis=0)
        return self.bias

    def close(self) -> None:
        self.stop_stream()
