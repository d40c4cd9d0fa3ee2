"""Schedules periodic stream samples on the simulated clock."""

from __future__ import annotations


class SampleSchedule:
    """Sample times every ``1/rate_hz`` on the simulated clock, from a start time.

    If the host falls far behind (a slow reader, a huge clock factor), samples older
    than ``max_backlog`` periods are skipped, as a real sensor's would be lost.
    """

    def __init__(self, rate_hz: float, max_backlog: int = 1000, report_on_advance: bool = False):
        if rate_hz <= 0:
            raise ValueError(f"stream rate must be > 0 Hz, got {rate_hz}")
        self.period_s = 1.0 / rate_hz
        self.max_backlog = max_backlog
        # On a discrete-event (manual) clock a sample is also reported at every advance
        # of time, so that "a sample from now" exists whenever time stands still: the
        # last sample of an advance is at the new time itself, and the world's one solve
        # of the advance is the state every reader of that instant (the camera) shares.
        self.report_on_advance = report_on_advance
        self.next_t: float | None = None
        self._last_t: float | None = None

    def start(self, now_s: float) -> None:
        self.next_t = now_s  # the first sample at once

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
        last = times[-1] if times else self._last_t
        if self.report_on_advance and last is not None and now_s > last:
            times.append(now_s)
        if times:
            self._last_t = times[-1]
        return times
