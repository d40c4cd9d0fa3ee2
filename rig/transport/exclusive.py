"""A serial port held by one process: its device node locked, and TIOCEXCL on real ttys.

Two locks beside the claim in the runtime folder (rig/ownership.py):

- pyserial's ``exclusive=True``: an advisory ``flock`` on the port's file descriptor, so a
  second opener that asks for it too (this tool, of any user) is refused.
- ``TIOCEXCL`` once open: the kernel refuses any further ``open`` of the tty, by any program,
  with EBUSY. Root (CAP_SYS_ADMIN) passes through it; the flock and the claim still hold.
  It is cleared (``TIOCNXCL``) before the port closes. Not on a pty: the kernel keeps a pty
  slave's flag while its master is open, so a holder killed before it could clear it would
  lock every later client out of a running simulator until it restarts.

A port held either way is ``DeviceBusy`` (naming the port; the rig adds the roles and the
holder where it can find it), never a "could not open port" traceback.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import termios

from rig.errors import DeviceBusy

# Unix98 pty slaves: majors 136–143 (Documentation/admin-guide/devices.txt)
PTY_SLAVE_MAJORS = range(136, 144)
BUSY_ERRNOS = (errno.EAGAIN, errno.EWOULDBLOCK, errno.EBUSY)  # flock taken; TIOCEXCL set


def lockable(url: str) -> bool:
    """A device path (not a ``socket://`` or other pyserial URL): its node can be locked."""
    return "://" not in url


def is_pty_slave(fd: int) -> bool:
    st = os.fstat(fd)
    return os.major(st.st_rdev) in PTY_SLAVE_MAJORS


def hold(fd: int, *, on_pty: bool = False) -> bool:
    """Set TIOCEXCL on the tty open on ``fd`` (on a pty only when ``on_pty``); True if set."""
    if not on_pty and is_pty_slave(fd):
        return False
    try:
        fcntl.ioctl(fd, termios.TIOCEXCL)
    except OSError:
        return False  # not a tty (a test's pipe): the flock still holds
    return True


def let_go(fd: int) -> None:
    """Clear TIOCEXCL (before closing: on a tty others still hold open, the flag would stay)."""
    with contextlib.suppress(OSError):
        fcntl.ioctl(fd, termios.TIOCNXCL)


def busy_error(url: str, exc: BaseException) -> DeviceBusy | None:
    """``DeviceBusy`` for pyserial's refusal of a port locked or held exclusively, else None."""
    if getattr(exc, "errno", None) not in BUSY_ERRNOS:
        return None
    how = "locked its node" if "exclusively lock" in str(exc) else "holds it exclusively (TIOCEXCL)"
    return DeviceBusy(url, detail=f"(it {how}; no claim of this user names it: another user's, or another program)")
