"""How a motion session ends: the signals it turns into exceptions, and the report of its end.

SIGINT, SIGTERM and SIGHUP (Ctrl-C, kill or systemd, a closed terminal or SSH session) raise
``MotionInterrupted`` naming the signal while ``SignalsAsExceptions`` is entered; ``describe``
words an ending as a run file's status and reason; ``StopReport`` is what ``on_stop`` receives.
"""

from __future__ import annotations

import signal
import threading
from dataclasses import dataclass, field
from types import FrameType
from typing import Any, Callable

from rig.early_signals import EARLY, HANDLED_SIGNALS


class MotionInterrupted(KeyboardInterrupt):
    """A signal stopped the motion; ``signal_name`` says which (SIGINT, SIGTERM, SIGHUP).
    ``secured``: a motion session's stop sequence has run for it (axes stopped, z lifted when
    pressed), so whoever catches it need not run one again."""

    def __init__(self, signal_name: str):
        self.signal_name = signal_name
        self.secured = False
        super().__init__(signal_name)

    @property
    def exit_code(self) -> int:
        """The shell convention for death by this signal: 128 + its number (SIGTERM 143, SIGHUP 129)."""
        return 128 + int(getattr(signal, self.signal_name))


def describe(exc: BaseException | None) -> tuple[str, str]:
    """(status, reason) for how a session ended: complete, interrupted (SIGTERM), aborted: Type: message."""
    if exc is None:
        return "complete", ""
    if isinstance(exc, MotionInterrupted):
        return "interrupted", f"interrupted ({exc.signal_name})"
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted", "interrupted (Ctrl-C)"
    return "aborted", f"aborted: {type(exc).__name__}: {exc}"


class SignalsAsExceptions:
    """While entered (main thread only; elsewhere Python cannot install handlers), the
    handled signals raise ``MotionInterrupted``; with ``holding`` set they are only noted
    in ``held``. A signal held since the command started (``EARLY``) is taken over on entry.
    The previous handlers come back on exit."""

    def __init__(self, *, holding: bool = False):
        self._previous: dict[int, Callable[[int, FrameType | None], Any] | int | None] = {}
        self.holding = holding
        self.held: str | None = None

    def __enter__(self) -> "SignalsAsExceptions":
        if threading.current_thread() is threading.main_thread():
            for name in HANDLED_SIGNALS:
                number = getattr(signal, name, None)
                if number is not None:
                    self._previous[number] = signal.signal(number, self._handle)
            self.held = self.held or EARLY.take()
        return self

    def _handle(self, signum, _frame) -> None:
        name = signal.Signals(signum).name
        if self.holding:
            self.held = self.held or name
            return
        raise MotionInterrupted(name)

    def raise_held(self) -> None:
        """Stop holding; a signal noted meanwhile is raised now."""
        self.holding = False
        held, self.held = self.held, None
        if held is not None:
            raise MotionInterrupted(held)

    def __exit__(self, *exc) -> None:
        for number, previous in self._previous.items():
            # None: a handler installed from C, which Python cannot reinstate; the default is the safe fallback.
            signal.signal(number, previous if previous is not None else signal.SIG_DFL)
        self._previous.clear()


@dataclass
class StopReport:
    """How a session ended, for ``on_stop`` (the acquisition writes it into the run file)."""

    what: str
    status: str  # complete | aborted | interrupted
    reason: str  # "" when complete
    error: BaseException | None
    cleanup_errors: list[str] = field(default_factory=list)  # a stop, lift or close that failed
    actions: list[str] = field(default_factory=list)  # what the stop sequence did ("z lifted ... because ...")
