"""Signals at any moment of a command that opens the rig (docs/safety.md, "Signals at any moment").

A motion session stops the axes and lifts z for a signal that lands while it is open. Around it
a command opens the rig, measures, prints and closes it, and a signal there used to end the
process with z left pressed. ``opened_safely`` holds SIGINT, SIGTERM and SIGHUP while the rig
opens (a signal held since the command's first instruction included: rig/early_signals.py),
and raises them once it is open; any ``MotionInterrupted`` that no session secured runs a
session's stop sequence (``secure``: stop every axis, lift z when it may be pressed) before it
goes on; the closing runs to its end, and a signal during it is raised after.
"""

from __future__ import annotations

import contextlib
import logging
from typing import Any, Callable, ContextManager, Iterator

from rig.errors import RigError
from rig.interruption import MotionInterrupted, SignalsAsExceptions

log = logging.getLogger("rig.motion")


def secure(rig, interrupted: MotionInterrupted) -> None:
    """The stop sequence of a motion session for a signal that landed outside one: every axis
    stopped, z lifted when it may be pressed (rig/lift.py), what was done logged. Nothing to do
    for a rig without a gauge (it cannot move) or with a session open (that session runs it)."""
    if interrupted.secured or rig.motion_session is not None or rig.gauge is None or rig.guard is None:
        return
    try:
        with rig.motion(f"the command ({interrupted.signal_name})", pending_signal=interrupted.signal_name):
            pass  # the held signal ends the session as it opens: its stop sequence runs
    except MotionInterrupted:
        pass
    except (RigError, OSError) as exc:
        log.error("after %s: stopping the rig failed: %s", interrupted.signal_name, exc)
    interrupted.secured = True


@contextlib.contextmanager
def opened_safely(opener: Callable[[], ContextManager[Any]], rig_of: Callable[[Any], Any] = lambda x: x) -> Iterator:
    """``with opened_safely(lambda: Rig.open(cfg)) as rig:`` — the rig opened with signals held,
    then signals as ``MotionInterrupted``, each one secured (``secure``) before it propagates.
    ``rig_of``: the rig in what ``opener`` yields (a tuple, say)."""
    signals = SignalsAsExceptions(holding=True)
    with signals:
        with opener() as opened:
            rig = rig_of(opened)
            try:
                signals.raise_held()  # a signal while it opened (or since the command began)
                yield opened
            except MotionInterrupted as exc:
                signals.holding = True  # the stop sequence and the closing run to their end
                secure(rig, exc)
                raise
            finally:
                signals.holding = True
        signals.raise_held()  # a signal while it closed: the command still ends by it
