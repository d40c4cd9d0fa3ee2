"""Elapsed time and time left, for progress lines: pure arithmetic, the clock handed in.

``Eta(total, clock)`` for a loop of known length (``line(done)`` → ``"1 min 05 s, about
40 s left"``); ``staged_left`` for a job of stages with expected durations (the main
job: scripts/main_job.sh calls ``python -m common.eta`` between its stages).
"""

from __future__ import annotations

import math
import sys
import time
from typing import Callable, Sequence


def format_duration(seconds: float) -> str:
    """``"7 s"``, ``"1 min 05 s"``, ``"2 h 03 min"``; a negative or non-finite value is ``"?"``."""
    if not math.isfinite(seconds) or seconds < 0:
        return "?"
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def time_left(done: float, total: float, elapsed_s: float) -> float | None:
    """Seconds left if the rest goes at the rate so far; None before anything is done."""
    if done <= 0 or total <= 0 or elapsed_s < 0 or not all(map(math.isfinite, (done, total, elapsed_s))):
        return None
    return max(0.0, elapsed_s * (total - done) / done)


class Eta:
    """Elapsed and time left of ``total`` units of work, timed from the first ``start()``
    (or construction) on ``clock`` (seconds, monotonic)."""

    def __init__(self, total: float, clock: Callable[[], float] = time.perf_counter, *, first: float = 0):
        self.total, self.clock, self.first = total, clock, first
        self.t0 = clock()

    def start(self, first: float = 0) -> None:
        """Restart the timer with ``first`` units already done before it (a resumed run)."""
        self.t0, self.first = self.clock(), first

    def elapsed(self) -> float:
        return self.clock() - self.t0

    def left(self, done: float) -> float | None:
        return time_left(done - self.first, self.total - self.first, self.elapsed())

    def line(self, done: float) -> str:
        """``"<elapsed>, about <left> left"``; ``"<elapsed>"`` alone while nothing is done or at the end."""
        elapsed = format_duration(self.elapsed())
        left = self.left(done)
        if left is None or done >= self.total:
            return elapsed
        return f"{elapsed}, about {format_duration(left)} left"


def staged_left(expected_s: Sequence[float], finished: int, elapsed_s: float) -> float:
    """Seconds left of a job whose stages were expected to take ``expected_s`` each, after
    ``finished`` of them took ``elapsed_s`` in all: the rest's expected time scaled by how
    the finished stages went against theirs (within ×0.5 to ×10, so one odd stage does not
    swing the estimate wildly)."""
    if finished < 0 or finished > len(expected_s):
        raise ValueError(f"finished stages {finished}: expected 0 to {len(expected_s)}")
    if any(not math.isfinite(e) or e < 0 for e in expected_s):
        raise ValueError(f"expected stage seconds must be finite and >= 0, got {list(expected_s)}")
    before, rest = sum(expected_s[:finished]), sum(expected_s[finished:])
    pace = 1.0 if before <= 0 or elapsed_s <= 0 else min(10.0, max(0.5, elapsed_s / before))
    return rest * pace


def main(argv: Sequence[str]) -> int:
    """``python -m common.eta EXPECTED_S,EXPECTED_S,... FINISHED ELAPSED_S``: prints the job's
    time left (``staged_left``) as ``about 2 min 10 s left``; a bad argument: one line, exit 2."""
    try:
        if len(argv) != 3:
            raise ValueError("expected 3 arguments: EXPECTED_S,EXPECTED_S,... FINISHED ELAPSED_S")
        expected = [float(x) for x in argv[0].split(",")]
        finished, elapsed = int(argv[1]), float(argv[2])
        if not math.isfinite(elapsed) or elapsed < 0:
            raise ValueError(f"elapsed seconds must be finite and >= 0, got {argv[2]!r}")
        left = staged_left(expected, finished, elapsed)
    except ValueError as exc:
        print(f"common.eta: {exc}", file=sys.stderr)
        return 2
    print(f"about {format_duration(left)} left")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
