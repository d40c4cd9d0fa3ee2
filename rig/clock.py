"""Injectable clocks.

Logic never calls ``time.sleep`` or ``time.monotonic`` directly: it takes a clock.
``SystemClock`` is real time, ``ScaledClock`` runs a simulated rig faster than real
time, and ``ManualClock`` is instant (sleeping advances it), for tests that hold a
move "in flight" and step through it.
"""

from __future__ import annotations

import threading
import time
from typing import Protocol


class Clock(Protocol):
    def now(self) -> float:
        """Monotonic time in seconds."""

    def sleep(self, dt_s: float) -> None:
        """Wait ``dt_s`` seconds of this clock's time."""


class SystemClock:
    """Real monotonic time."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, dt_s: float) -> None:
        if dt_s > 0:
            time.sleep(dt_s)


class ScaledClock:
    """Simulated time running ``factor`` times faster than real time.

    Shared by the simulators and the drivers of a simulated rig so that a two-hour
    protocol runs in minutes while every serial exchange still happens for real.
    """

    def __init__(self, factor: float = 1.0, start_s: float = 0.0):
        if factor <= 0:
            raise ValueError(f"clock factor must be > 0, got {factor}")
        self.factor = factor
        self._t0_real = time.monotonic()
        self._t0 = start_s

    def now(self) -> float:
        return self._t0 + (time.monotonic() - self._t0_real) * self.factor

    def sleep(self, dt_s: float) -> None:
        if dt_s > 0:
            time.sleep(dt_s / self.factor)


class ManualClock:
    """Time that only moves when told to; ``sleep`` advances it instantly.

    Thread-safe: a driver thread sleeping and a simulator thread reading the time see
    one consistent value.
    """

    def __init__(self, start_s: float = 0.0):
        self._t = start_s
        self._lock = threading.Lock()
        self._listeners: list = []

    def add_listener(self, callback) -> None:
        """``callback()`` runs after every advance, in the advancing thread: simulated
        devices emit what became due before the advancing code reads them."""
        self._listeners.append(callback)

    def remove_listener(self, callback) -> None:
        self._listeners.remove(callback)

    def now(self) -> float:
        # One attribute read is atomic; the lock only keeps concurrent advances from losing one.
        return self._t

    def sleep(self, dt_s: float) -> None:
        if dt_s > 0:
            self.advance(dt_s)

    def advance(self, dt_s: float) -> None:
        if dt_s < 0:
            raise ValueError("a clock cannot go backwards")
        with self._lock:
            self._t += dt_s
        for callback in list(self._listeners):
            callback()
