"""Fault injection as a frame manipulator between a simulated device and its wire.

The device models never know about faults: every reply (and every streamed frame)
passes through ``FaultInjector.apply``, which may drop it, garble a byte, cut it short
or hold it back (in simulated seconds: a device answering late). ``stall_next`` instead
holds the simulator thread itself back in real time, as a CPU-starved thread would.
Tests arm faults by count ("garble the next reply").
"""

from __future__ import annotations

import random
import threading
from dataclasses import dataclass


@dataclass
class FaultCounts:
    dropped: int = 0
    garbled: int = 0
    truncated: int = 0
    delayed: int = 0
    stalled: int = 0


class FaultInjector:
    def __init__(self, seed: int = 0):
        self._rng = random.Random(seed)
        self._lock = threading.Lock()
        self._drop = 0
        self._garble = 0
        self._truncate = 0
        self._delay = 0
        self._delay_s = 0.0
        self._stall = 0
        self._stall_s = 0.0
        self.counts = FaultCounts()

    def drop_next(self, n: int = 1) -> None:
        with self._lock:
            self._drop += n

    def garble_next(self, n: int = 1) -> None:
        with self._lock:
            self._garble += n

    def truncate_next(self, n: int = 1) -> None:
        with self._lock:
            self._truncate += n

    def delay_next(self, n: int, delay_s: float) -> None:
        """Hold the next ``n`` replies back by ``delay_s`` seconds of the simulator's clock
        (real seconds on a real-time clock): the device answers late."""
        with self._lock:
            self._delay += n
            self._delay_s = delay_s

    def stall_next(self, n: int, real_s: float) -> None:
        """Before handling each of the next ``n`` inputs, the simulator thread waits
        ``real_s`` real seconds while no simulated time passes (a machine under load)."""
        with self._lock:
            self._stall += n
            self._stall_s = real_s

    @property
    def stall_armed(self) -> bool:
        """A stall is waiting for the next input (only the simulator's own thread may take it)."""
        return self._stall > 0

    def take_stall(self) -> float:
        """Real seconds the simulator thread should stall now (0 when none is armed)."""
        with self._lock:
            if not self._stall:
                return 0.0
            self._stall -= 1
            self.counts.stalled += 1
            return self._stall_s

    def clear(self) -> None:
        with self._lock:
            self._drop = self._garble = self._truncate = self._delay = self._stall = 0

    def apply(self, frame: bytes) -> tuple[bytes | None, float]:
        """(bytes to send or None, delay in clock seconds) for one outgoing frame."""
        with self._lock:
            if self._drop:
                self._drop -= 1
                self.counts.dropped += 1
                return None, 0.0
            delay = 0.0
            if self._delay:
                self._delay -= 1
                self.counts.delayed += 1
                delay = self._delay_s
            if self._garble and frame:
                self._garble -= 1
                self.counts.garbled += 1
                frame = self._garbled(frame)
            if self._truncate and len(frame) > 1:
                self._truncate -= 1
                self.counts.truncated += 1
                frame = frame[: len(frame) // 2]
            return frame, delay

    def _garbled(self, frame: bytes) -> bytes:
        # Change one byte other than a line terminator, so framing still finds the end
        # and only the content (checksum, CRC, digits) is wrong.
        positions = [i for i, b in enumerate(frame) if b not in (0x0A, 0x0D)] or [0]
        i = self._rng.choice(positions)
        b = frame[i]
        new = b ^ (1 << self._rng.randrange(8))
        if new in (0x0A, 0x0D):
            new ^= 0x40
        return frame[:i] + bytes([new]) + frame[i + 1 :]
