"""On a discrete clock, a gauge whose reader thread alone reads an in-process simulator waits until that
thread has read what the simulator sent up to this instant: a reader starved of the CPU cannot leave the
newest sample behind simulated time (the guard then stopped a simulated run for a gauge "240 ms late"
on an idle machine, tests/test_sim_speed.py's threaded half)."""

from __future__ import annotations

import struct
import threading

import numpy as np

from rig.clock import ManualClock
from rig.drivers.gauge_base import GaugeBase
from rig.drivers.wrench_stream import FrameSync

FRAME = struct.Struct("<2s6f")  # a header and six floats: this test's own wire format


class _HeldLine:
    """The simulator's line: frames put on it stay there until the reader is let through, which happens
    only when someone asks how many bytes are in flight (a reader thread that runs only when waited for)."""

    def __init__(self):
        self.chunks: list[bytes] = []
        self.lock = threading.Lock()
        self.go = threading.Event()

    def send(self, values) -> None:
        with self.lock:
            self.chunks.append(FRAME.pack(b"\xaa\x55", *values))

    def in_flight(self) -> int:
        with self.lock:
            n = sum(len(c) for c in self.chunks)
        if n:
            self.go.set()
        return n

    def read_chunk(self) -> bytes:
        if not self.go.wait(0.02):
            return b""
        self.go.clear()
        with self.lock:
            data, self.chunks = b"".join(self.chunks), []
        return data


class _Gauge(GaugeBase):
    name = label = "held gauge"

    def __init__(self, clock, line: _HeldLine, knows_in_flight: bool):
        super().__init__(clock)
        self.line, self.knows = line, knows_in_flight

    def _stream_open(self):
        return self.line.read_chunk

    def _stream_close(self) -> None:
        pass

    def _stream_in_flight(self):
        return self.line.in_flight if self.knows else None

    def make_sync(self):
        return FrameSync(b"\xaa\x55", FRAME.size, lambda frame: True)

    def decode(self, frame: bytes) -> np.ndarray:
        return np.array(FRAME.unpack(frame)[1:], dtype=float)


def _newest_after_a_held_sample(knows_in_flight: bool):
    clock = ManualClock()
    line = _HeldLine()
    gauge = _Gauge(clock, line, knows_in_flight)
    gauge.start_stream()
    try:
        line.send([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
        line.go.set()
        assert gauge.buffer.wait_beyond(0, 5.0)  # the first sample, at t = 0
        clock.advance(0.3)
        line.send([0.0, 0.0, 2.0, 0.0, 0.0, 0.0])  # sent at t = 0.3, not read yet
        return gauge.read()
    finally:
        gauge.stop_stream()


def test_the_newest_sample_is_this_instants_once_the_reader_has_read_the_line():
    sample = _newest_after_a_held_sample(knows_in_flight=True)
    assert sample.t_s == 0.3 and sample.fz_N == 2.0


def test_without_knowing_what_is_in_flight_the_sample_is_the_older_one():
    """What the guard saw before: the sample of 0.3 s ago (within the gauge's stale bound, so read as is)."""
    sample = _newest_after_a_held_sample(knows_in_flight=False)
    assert sample.t_s == 0.0 and sample.fz_N == 1.0
