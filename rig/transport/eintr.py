"""Retry system calls interrupted by a signal (EINTR).

Python retries most blocking calls itself (PEP 475: read, write, select, sockets),
but not ``termios.tcdrain``, which pyserial's ``flush`` calls: a signal arriving
while bytes drain (a profiler attaching, a timer, any handled signal) made it raise
``termios.error(4, 'Interrupted system call')`` and abort a run.

Only the EINTR error is retried. An exception that a Python signal handler raises
(the motion context turns SIGINT, SIGTERM and SIGHUP into one) is not an OSError
with EINTR, so it propagates from the retry loop as from any other call.
"""

from __future__ import annotations

import errno

try:
    import termios

    TERMIOS_ERROR: tuple = (termios.error,)
except ImportError:  # not POSIX
    TERMIOS_ERROR = ()


def is_eintr(exc: BaseException) -> bool:
    """True for an OSError/InterruptedError or termios.error carrying EINTR."""
    if isinstance(exc, OSError):
        return exc.errno == errno.EINTR
    if TERMIOS_ERROR and isinstance(exc, TERMIOS_ERROR):
        return bool(exc.args) and exc.args[0] == errno.EINTR
    return False


def retry_eintr(fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, called again for as long as it fails with EINTR.

    Only for calls that are safe to repeat after EINTR (nothing was transferred:
    tcdrain, select, a read that returned no data).
    """
    while True:
        try:
            return fn(*args, **kwargs)
        except (OSError, *TERMIOS_ERROR) as exc:
            if not is_eintr(exc):
                raise
