"""common/scheduling.py: threads a library switched to real-time priority are put back on the caller's
policy (SVT-AV1 does it as root: tests/test_lerobot_exchange.py shows it on a real export)."""

from __future__ import annotations

import os
import threading

import pytest

from common.scheduling import kept_normal, real_time_threads


def _switched_thread(started: threading.Event, done: threading.Event, tids: list[int]) -> None:
    """What such a library does: this thread to SCHED_FIFO at the top priority."""
    tids.append(threading.get_native_id())
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(os.sched_get_priority_max(os.SCHED_FIFO)))
    except PermissionError:
        tids.clear()  # not allowed here (not root): nothing to undo
    started.set()
    done.wait(10)


@pytest.mark.realtime  # in the lane: a lowering by the lane (tests/realtime_priority.py) would put it back first
def test_threads_a_library_switched_to_real_time_are_put_back():
    started, done, tids = threading.Event(), threading.Event(), []
    worker = threading.Thread(target=_switched_thread, args=(started, done, tids), daemon=True)
    try:
        with kept_normal() as settle:
            worker.start()
            started.wait(10)
            if not tids:
                pytest.skip("this user may not switch a thread to real time (root may)")
            assert real_time_threads() == tids  # the library's thread, and only it
            assert settle() == 1
            assert os.sched_getscheduler(tids[0]) == os.SCHED_OTHER and real_time_threads() == []
            os.sched_setscheduler(tids[0], os.SCHED_FIFO, os.sched_param(1))  # again, before the end
        assert os.sched_getscheduler(tids[0]) == os.SCHED_OTHER  # leaving puts it back too
    finally:
        done.set()
        worker.join(10)
    assert os.sched_getscheduler(0) == os.SCHED_OTHER
