"""This process's threads kept on the scheduling policy they started with (Linux).

SVT-AV1, the encoder behind ``dataset export --codec av1``, switches the thread that opens it to
SCHED_FIFO at the top real-time priority (99) whenever it is allowed to (as root), and every thread
that thread creates afterwards inherits it: its own encoding threads, and every command the process
starts later. A real-time thread runs ahead of every normal one on the machine, whatever its nice
value: a busy one holds a core for as long as it likes, and a rig's motion guard, its gauge stream
or a simulator's device threads on the same machine wait (measured here: a normal process that
wakes every 5 ms was kept waiting 0.4-0.95 s while such an export ran). ``kept_normal`` puts
every thread that such a library switched back on the caller's policy.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator

_REAL_TIME = tuple(getattr(os, name) for name in ("SCHED_FIFO", "SCHED_RR") if hasattr(os, name))
_RESET_ON_FORK = getattr(os, "SCHED_RESET_ON_FORK", 0)  # a flag sched_getscheduler reports with the policy


def _policy(tid: int) -> int:
    return os.sched_getscheduler(tid) & ~_RESET_ON_FORK


def is_real_time(tid: int) -> bool:
    """Whether thread ``tid`` (any process's, Linux) runs on a real-time policy; OSError when it has ended."""
    return bool(_REAL_TIME) and _policy(tid) in _REAL_TIME


def _threads() -> list[int]:
    try:
        return [int(tid) for tid in os.listdir("/proc/self/task")]
    except OSError:
        return []  # not Linux


def real_time_threads() -> list[int]:
    """The thread ids of this process on a real-time policy (SCHED_FIFO, SCHED_RR)."""
    if not _REAL_TIME:
        return []
    found = []
    for tid in _threads():
        try:
            if is_real_time(tid):
                found.append(tid)
        except OSError:
            continue  # ended meanwhile
    return found


def back_to(policy: int, priority: int, keep: frozenset[int] = frozenset()) -> int:
    """Every real-time thread of this process but those in ``keep`` (real time before the library ran:
    someone's choice) on ``policy`` at ``priority`` again; how many were changed."""
    changed = 0
    for tid in real_time_threads():
        if tid in keep:
            continue
        try:
            os.sched_setscheduler(tid, policy, os.sched_param(priority))
            changed += 1
        except OSError:
            continue  # ended meanwhile, or not allowed: nothing to undo then
    return changed


@contextlib.contextmanager
def kept_normal() -> Iterator[Callable[[], int]]:
    """Inside: call a library that may switch threads to real time. The yielded ``settle()`` puts every
    thread it switched back on the policy this thread had (call it once the library has made its
    threads); leaving does it again. A caller that itself runs on a real-time policy (chrt) is left alone."""
    if not _REAL_TIME or not hasattr(os, "sched_getscheduler"):
        yield lambda: 0
        return
    policy, priority = _policy(0), os.sched_getparam(0).sched_priority
    if policy in _REAL_TIME:
        yield lambda: 0  # asked for by whoever started us: not ours to change
        return
    keep = frozenset(real_time_threads())  # threads already real time: chosen by someone, left so
    try:
        yield lambda: back_to(policy, priority, keep)
    finally:
        back_to(policy, priority, keep)
