"""Schedules periodic stream samples on the simulated clock."""

from __future__ import annotations


class SampleSchedule:
    """Sample times every ``1/rate_hz`` on the simulated clock, from a start time.

    If the host falls far behind (a slow reader, a huge clock factor), samples older
    than ``max_backlog`` periods are skipped, as a real sensor's would be lost.
    """

    def __init__(self, rate_hz: float, max_backlog: int = 1000):
        if rate_hz <= 0:
            raise ValueError(f"stream rate must be > 0 Hz, got {rate_hz}")
        self.period_s = 1.0 / rate_hz
        self.max_backlog = max_backlog
        self.next_t: float | None = None

    def start(self, now_s: float) -> None:
        self.next_t = now_s + self.period_s

    def stop(self) -> None:
        self.next_t = None

    def due(self, now_s: float) -> list[float]:
        if self.next_t is None:
            return []
        if now_s - self.next_t > self.max_backlog * self.period_s:
            self.next_t = now_s - self.max_backlog * self.period_s
        times = []
        while self.next_t <= now_s:
            times.append(self.next_t)
            self.next_t += self.period_s
        return times
