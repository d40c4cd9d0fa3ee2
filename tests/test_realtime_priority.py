"""The other test workers are lowered, with all they started, while realtime tests run (conftest.py)."""

from __future__ import annotations

import os
import subprocess
import sys

import realtime_priority as rp

# a process that starts a child and a thread, then waits on its stdin
PARENT = """
import subprocess, sys, threading
child = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)
threading.Thread(target=sys.stdin.read, daemon=True).start()
print(child.pid, flush=True)
sys.stdin.readline()
child.stdin.close()
child.wait()
"""


def test_a_worker_and_everything_it_started_are_lowered_and_this_process_is_not(tmp_path, monkeypatch):
    parent = subprocess.Popen([sys.executable, "-c", PARENT], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        child = int(parent.stdout.readline())
        (tmp_path / "gw1.pid").write_text(str(parent.pid))
        monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw0")
        rp.register_worker(tmp_path)
        assert (tmp_path / "gw0.pid").read_text() == str(os.getpid())
        mine = os.getpriority(os.PRIO_PROCESS, 0)
        threads = [int(t) for pid in (parent.pid, child) for t in os.listdir(f"/proc/{pid}/task")]
        assert len(threads) >= 3  # the parent's main thread and its reader thread, the child
        assert rp.lower_other_workers(tmp_path) == len(threads)
        assert all(os.getpriority(os.PRIO_PROCESS, t) == rp.OTHERS_NICE for t in threads)
        assert os.getpriority(os.PRIO_PROCESS, 0) == mine  # this worker keeps its priority
        assert rp.lower_other_workers(tmp_path) == 0  # already lowered: nothing to do
    finally:
        parent.stdin.write("\n")
        parent.stdin.close()
        parent.wait(timeout=30)


def test_descendants_follow_the_process_tree():
    tree = {1: [2, 3], 3: [4], 4: [5], 9: [10]}
    assert sorted(rp.descendants(1, tree)) == [1, 2, 3, 4, 5]
    assert rp.descendants(7, tree) == [7]
