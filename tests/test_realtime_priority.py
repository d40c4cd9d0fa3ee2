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


def test_a_worker_a_library_switched_to_real_time_is_put_back_and_lowered(tmp_path):
    """A worker's thread on SCHED_FIFO (SVT-AV1 does it to its caller, as root) runs ahead of every normal
    thread whatever its nice value: lowering takes it off real time too."""
    switched = (
        "import os, sys\nos.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))\n"
        "print(1, flush=True)\nsys.stdin.readline()\n"
    )
    worker = subprocess.Popen(
        [sys.executable, "-c", switched], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        if worker.stdout.readline().strip() != "1":
            pytest.skip("this user may not switch a process to real time (root may)")
        assert os.sched_getscheduler(worker.pid) == os.SCHED_FIFO
        (tmp_path / "gw1.pid").write_text(str(worker.pid))
        rp.register_worker(tmp_path, "gw0")
        assert rp.lower_other_workers(tmp_path) >= 1  # off real time (and lowered, unless started so)
        assert os.sched_getscheduler(worker.pid) == os.SCHED_OTHER
        assert os.getpriority(os.PRIO_PROCESS, worker.pid) == rp.OTHERS_NICE
    finally:
        worker.stdin.write("\n")
        worker.stdin.close()
        worker.wait(timeout=30)


def test_descendants_follow_the_process_tree():
    tree = {1: [2, 3], 3: [4], 4: [5], 9: [10]}
    assert sorted(rp.descendants(1, tree)) == [1, 2, 3, 4, 5]
    assert rp.descendants(7, tree) == [7]


def test_an_alone_turn_waits_for_the_other_lanes_test_and_shared_turns_do_not(tmp_path):
    import threading

    got = []

    def take(alone: bool) -> None:
        with rp.turn(tmp_path, alone):
            got.append(alone)

    with rp.turn(tmp_path, alone=False):  # the other lane's test in progress
        beside = threading.Thread(target=take, args=(False,))
        beside.start()
        beside.join(timeout=10)
        assert got == [False]  # a shared turn beside it at once
        alone = threading.Thread(target=take, args=(True,))
        alone.start()
        alone.join(timeout=0.5)
        assert alone.is_alive() and got == [False]  # the alone test waits
    alone.join(timeout=10)
    assert got == [False, True]  # and runs once the other test has ended


def test_lanes_keep_files_whole_and_balance_their_time():
    ids = {f"tests/{f}::t{i}" for f in ("test_host_signals.py", "test_check_axes.py", "test_new.py") for i in range(3)}
    one = rp.lanes(ids, 1)
    assert set(one.values()) == {"realtime-0"} and set(one) == ids
    two = rp.lanes(ids, 2)
    assert {two[f"tests/test_check_axes.py::t{i}"] for i in range(3)} == {"realtime-1"}  # whole files
    assert two["tests/test_host_signals.py::t0"] == "realtime-0"  # the longest file first
    assert two["tests/test_new.py::t2"] == "realtime-1"  # 103 + 20 s beside 147 s


# a test file of the inner run: each test notes its worker and its nice value as it runs
NOTING = """
import os
import pytest

def note(name):
    with open(os.environ["NOTES"], "a") as f:
        f.write(f"{os.environ['PYTEST_XDIST_WORKER']} {name} {os.getpriority(os.PRIO_PROCESS, 0)}\\n")
"""


@pytest.mark.realtime  # its inner run's realtime tests assert real time: this one runs where they would
def test_on_several_processes_realtime_tests_run_in_their_lanes_never_lowered(tmp_path):
    """Three files of realtime tests among 40 others, on four workers: each file's realtime tests in
    one worker, each lane (``LANES``) on a worker of its own, every realtime test at its worker's own
    priority, and a lane's worker lowered for the other tests it runs after its lane (xdist's own
    grouping is silently lost on pytest 9.2: pytest-dev/pytest-xdist#1386)."""
    root = Path(__file__).resolve().parents[1]
    tests = tmp_path / "tests"
    tests.mkdir()
    for name in ("conftest.py", "realtime_priority.py"):
        (tests / name).write_text((root / "tests" / name).read_text())
    (tmp_path / "pytest.ini").write_text("[pytest]\nmarkers =\n    realtime: real time\n")
    for f in ("a", "b", "c"):
        marked = [f"@pytest.mark.realtime\ndef test_{f}{i}():\n    note('{f}{i}')\n" for i in range(2)]
        (tests / f"test_rt_{f}.py").write_text(NOTING + "\n".join(marked))
    plain = [f"def test_plain{i}():\n    note('plain{i}')\n" for i in range(40)]
    (tests / "test_plain.py").write_text(NOTING + "\n".join(plain))
    notes = tmp_path / "notes.txt"
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}  # a run of its own
    env.update(NOTES=str(notes), PYTHONPATH=str(root))
    out = subprocess.run(
        [sys.executable, "-m", "pytest", "-n", "4", "--dist", "loadgroup", "-q", "-p", "no:cacheprovider", "tests"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
        env=env,
    )
    assert out.returncode == 0, out.stdout[-3000:]
    lines = notes.read_text().splitlines()
    ran = {name: (worker, int(nice)) for worker, name, nice in (line.split() for line in lines)}
    assert len(ran) == 46, sorted(ran)
    mine = os.getpriority(os.PRIO_PROCESS, 0)
    lane_of = {f: {ran[f"{f}{i}"][0] for i in range(2)} for f in "abc"}
    assert all(len(workers) == 1 for workers in lane_of.values()), lane_of  # a file's tests in one worker
    lane_workers = set().union(*lane_of.values())
    assert len(lane_workers) == rp.LANES, lane_of  # the lanes, a worker each
    assert all(ran[f"{f}{i}"][1] == mine for f in "abc" for i in range(2)), ran  # never lowered
    after_lane = [nice for worker, nice in (ran[f"plain{i}"] for i in range(40)) if worker in lane_workers]
    assert all(nice == rp.OTHERS_NICE for nice in after_lane), ran
    assert len({worker for worker, _ in ran.values()}) >= 3  # the others spread over the workers
