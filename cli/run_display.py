"""What `rig run-protocol` shows while it runs: a live bar on a terminal, whole lines in a log.

On a terminal: the protocol, level and phase, a bar, frames done of planned, the time left
(labelled) and the latest wrench with its units. When stdout is not a terminal (a log file, a
pipe, the main job's background collection) a bar cannot redraw, so one full line is printed at
the start of each level and phase and at the end, never cut to 80 columns.
"""

from __future__ import annotations

from typing import Any

from rich.console import Console

from cli.options import fixed
from common.eta import Eta

LOG_WIDTH = 400  # a line in a log is never wrapped or cut below this


def output_console() -> Console:
    """A console for stdout: the terminal's own width, or whole lines when stdout is not a terminal."""
    console = Console()
    return console if console.is_terminal else Console(width=LOG_WIDTH, soft_wrap=True)


def wrench_text(w) -> str:
    """'Fz   0.72 N  Fx +0.13 N  Fy -0.02 N  Mz  +0.44 N·mm' (never "-0.00")."""
    return (
        f"Fz {fixed(w[2], 2, sign=False):>6} N  Fx {fixed(w[0], 2):>5} N  Fy {fixed(w[1], 2):>5} N  "
        f"Mz {fixed(w[5], 2):>6} N·mm"
    )


class RunDisplay:
    """``with RunDisplay(console, name, frames) as show: show(progress)`` for each frame."""

    def __init__(self, console: Console, name: str, frames: int, clock=None):
        self.console, self.name, self.frames = console, name, frames
        self.eta = Eta(frames) if clock is None else Eta(frames, clock)
        self._bar: Any = None
        self._task: Any = None
        self._last: tuple | None = None
        self._first_frame: int | None = None

    def __enter__(self) -> "RunDisplay":
        if self.console.is_terminal:
            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

            self._bar = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                TextColumn("{task.completed}/{task.total} frames"),
                TextColumn("left"),
                TimeRemainingColumn(),
                TextColumn("{task.fields[wrench]}"),
                console=self.console,
                transient=False,
            )
            self._bar.__enter__()
            self._task = self._bar.add_task(self.name, total=self.frames, wrench="")
        return self

    def __call__(self, p) -> None:
        if self._first_frame is None:  # a resumed run: the rate counts from where it resumed
            self._first_frame = p.frame
            self.eta.start(first=p.frame)
        where = f"{self.name} L{p.level} {p.phase}"
        if self._bar is not None:
            self._bar.update(self._task, completed=p.frame, description=f"{where:24s}", wrench=wrench_text(p.wrench))
            return
        key = (p.level, p.phase)
        if key != self._last or p.frame >= p.frames:
            self._last = key
            self.console.print(
                f"{where}: {p.frame}/{p.frames} frames, {self.eta.line(p.frame)}; {wrench_text(p.wrench)}",
                highlight=False,
            )

    def __exit__(self, *exc) -> None:
        if self._bar is not None:
            self._bar.__exit__(*exc)
