"""The other test workers are lowered, with all they started, while realtime tests run (conftest.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
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


@pytest.mark.realtime  # on several processes: in the realtime tests' worker, the one never lowered
def test_a_worker_and_everything_it_started_are_lowered_and_this_process_is_not(tmp_path):
    parent = subprocess.Popen([sys.executable, "-c", PARENT], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        child = int(parent.stdout.readline())
        (tmp_path / "gw1.pid").write_text(str(parent.pid))
        rp.register_worker(tmp_path, "gw0")
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


@pytest.mark.realtime  # its inner run's realtime tests assert real time: this one runs where they would
def test_on_several_processes_every_realtime_test_runs_in_one_worker(tmp_path):
    """Two realtime tests of two files, among 40 others, on three workers: one worker runs both
    (xdist's own grouping is silently lost on pytest 9.2: pytest-dev/pytest-xdist#1386)."""
    files = ["tests/test_gauges.py", "tests/test_wire_robustness.py"]
    out = subprocess.run(
        [sys.executable, "-m", "pytest", "-n", "3", "--dist", "loadgroup", "-v", "-p", "no:cacheprovider", *files],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=Path(__file__).resolve().parents[1],
        env={k: v for k, v in os.environ.items() if not k.startswith("PYTEST_XDIST")},  # a run of its own
    )
    assert out.returncode == 0, out.stdout[-3000:]
    workers = {}
    for line in out.stdout.splitlines():
        if "PASSED" in line and line.startswith("[gw"):
            workers[line.split()[-1]] = line.split()[0]
    realtime = [
        "tests/test_gauges.py::test_ft300_sensor_that_keeps_streaming_is_a_typed_timeout",
        "tests/test_wire_robustness.py::test_write_and_flush_complete_while_signals_arrive",
    ]
    assert all(r in workers for r in realtime), sorted(workers)
    assert len({workers[r] for r in realtime}) == 1, {r: workers[r] for r in realtime}
    assert len(set(workers.values())) >= 2  # the others spread over the workers
