"""Signals held from a command's first instruction (docs/safety.md, "Signals at any moment").

A signal that lands while Python imports the command or while the rig opens must still stop the
axes and lift z, which only a motion session can do (rig/motion.py). ``EARLY.install()`` — the
first thing a moving command runs (cli/__init__.py) — notes the first SIGINT, SIGTERM or SIGHUP
instead of acting on it; the rig's opening and every motion session take it over
(``SignalsAsExceptions`` in rig/interruption.py); ``release`` gives the signals back their
default action and delivers one that nobody took. Standard library only: it must be quick to
import, since nothing is protected before it runs.
"""

from __future__ import annotations

import signal
import threading

HANDLED_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")  # Ctrl-C, kill/systemd, a closed terminal or SSH session
# The rig commands that move (cli/rig_app.py): their signals are held from the first instruction.
MOVING_COMMANDS = frozenset({"jog", "home", "find-contact", "check-axes", "run-protocol"})


class EarlyHold:
    """``install`` (main thread only) notes the first signal instead of acting on it; ``take``
    hands it over; ``release`` gives the signals back their default action and delivers a signal
    that nobody took."""

    def __init__(self):
        self.held: str | None = None
        self._installed: list[int] = []

    def _note(self, signum, _frame) -> None:
        self.held = self.held or signal.Signals(signum).name

    def install(self) -> None:
        if threading.current_thread() is not threading.main_thread() or self._installed:
            return
        for name in HANDLED_SIGNALS:
            number = getattr(signal, name, None)
            if number is not None:
                signal.signal(number, self._note)
                self._installed.append(number)

    @property
    def active(self) -> bool:
        return bool(self._installed)

    def take(self) -> str | None:
        held, self.held = self.held, None
        return held

    def release(self) -> None:
        """Default actions back; a signal held and not taken is delivered now."""
        if threading.current_thread() is not threading.main_thread():
            return
        for number in self._installed:
            if signal.getsignal(number) == self._note:
                signal.signal(number, signal.SIG_DFL if number != signal.SIGINT else signal.default_int_handler)
        self._installed.clear()
        held = self.take()
        if held is not None:
            signal.raise_signal(getattr(signal, held))


EARLY = EarlyHold()  # the process's one early hold (cli/__init__.py installs it for the moving commands)


def moving_command(argv: list[str]) -> bool:
    """Whether ``argv`` runs a rig command that moves: ``rig jog …``, ``python -m cli rig jog …``."""
    words = [w for w in argv[1:] if not w.startswith("-")]
    program = argv[0].rsplit("/", 1)[-1] if argv else ""
    if program != "rig":
        if not words or words[0] != "rig":
            return False
        words = words[1:]
    return bool(words) and words[0] in MOVING_COMMANDS


def hold_if_moving(argv: list[str]) -> None:
    """Install the early hold when ``argv`` is a moving rig command; a signal it holds that no
    session took is delivered when the process ends (its exit status still says which)."""
    if moving_command(argv):
        import atexit

        EARLY.install()
        atexit.register(EARLY.release)
