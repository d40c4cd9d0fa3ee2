"""The gauge behaviour every gauge driver shares (``GaugeBase``): tare, fresh reads and a
sample interpolated at a frame's timestamp, polled or from the stream that
rig/drivers/wrench_stream.py reads and buffers. A driver subclasses it and provides the bytes.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from rig.clock import Clock
from rig.drivers.wrench_stream import IN_FLIGHT_WAITS, STREAM_POLL_S, FrameCutter, Inline, StreamReader, WrenchBuffer
from rig.errors import DeviceTimeout
from rig.types import Wrench


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

    def _stream_in_flight(self) -> Callable[[], int] | None:
        """Bytes an in-process simulator has sent on the stream that were not read yet (None: none can
        know, as on hardware); see ``_await_taken``."""
        return None

    def _await_taken(self) -> None:
        """On a discrete clock with the reader thread alone reading a simulator in this process: wait
        (real time, bounded) until it has read what the simulator sent up to this instant. The clock
        stands still meanwhile, so a starved reader thread cannot leave the newest sample behind
        simulated time (a gauge "240 ms late" on an idle machine)."""
        in_flight = self._stream_in_flight()
        if in_flight is None:
            return
        for _ in range(IN_FLIGHT_WAITS):
            count = self.buffer.total
            if not in_flight():
                return
            self.buffer.wait_beyond(count, STREAM_POLL_S)

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
        if hasattr(self.clock, "add_listener"):
            # A simulated rig on discrete time: what its gauge sent up to this instant is on the
            # line; take it now (or wait until the reader thread has), so that the newest sample is
            # this instant's whatever the reader thread's scheduling (the guard's checks are then
            # the same on every run).
            if self._reader.inline:
                self._reader.take_in_flight()
            else:
                self._await_taken()
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
