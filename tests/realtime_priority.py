"""Realtime tests first in the CPU, the other test processes after them (Linux scheduling priority).

The suite runs on several processes (pytest-xdist). Tests marked ``realtime`` assert what happens at a
moment of real time, so a loaded machine must not delay them. They run in ``LANES`` lanes (now one;
never more than the workers less one): each lane is one work unit of the scheduler below, one worker
running its tests one after the other, and a test file's realtime tests stay in one lane. While they
run, the workers of no lane and everything they started (threads, commands, simulators, browsers) are
lowered to nice ``OTHERS_NICE``: the kernel then gives the realtime tests the cores they ask for at
once, and the other workers the rest, instead of stopping them. With several lanes a realtime test
shares the cores with one other realtime test, except one marked ``realtime(alone=True)`` (``turn``);
a lane's worker lowers itself when its lane is done and it goes on with other tests.

Only ever raising a process's nice value needs no privilege (lowering it back would), so a lowered
worker stays lowered for the rest of the run; none of its tests asserts real time.

The units: xdist's own ``--dist loadgroup`` groups by renaming node ids, which pytest 9.2 no longer
lets it do (pytest-dev/pytest-xdist#1386: the groups are silently ignored). So each worker writes the
realtime tests it collected to the run's folder, and the scheduler (``RealtimeFirst``, installed by
tests/conftest.py for ``--dist loadgroup``) reads them, makes the lanes, hands them out before any
other unit, and marks their workers in the run's folder before the first test starts.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator
from pathlib import Path

from xdist.scheduler import LoadScopeScheduling

from common.scheduling import is_real_time

OTHERS_NICE = 19  # the lowest priority: CFS weight 15 against a default task's 1024
LANES = 1  # at most (two lanes were tried: a realtime test beside another failed in 2 of 5 full runs)
UNIT = "realtime"  # the scheduler's name of a lane's unit: realtime-0, realtime-1
# Seconds of wall time each file's realtime tests took in their lane (three workers, idle 2-core VM,
# 2026-11-29), only to balance the lanes; a file not listed counts DEFAULT_S.
FILE_SECONDS = {
    "test_host_signals.py": 147,
    "test_check_axes.py": 103,
    "test_interrupted_lift.py": 80,
    "test_main_job_continues.py": 78,
    "test_resume_levels.py": 58,
    "test_console_page.py": 47,
    "test_console.py": 41,
    "test_first_hour_cli.py": 28,
    "test_realtime_priority.py": 10,
    "test_console_truth.py": 9,
    "test_acquisition.py": 7,
    "test_sim_speed.py": 5,
}
DEFAULT_S = 20


def register_worker(folder: Path, worker: str) -> None:
    """Note this worker's pid in ``folder`` (the run's shared temporary folder); ``worker``: its id (gw0...)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{worker}.pid").write_text(str(os.getpid()))


def processes() -> list[tuple[int, str, int, int]]:
    """Every process now: (pid, command name, parent pid, process group), from /proc/<pid>/stat."""
    out = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue  # ended meanwhile
        name = stat[stat.index("(") + 1 : stat.rindex(")")]  # the command name may hold spaces and brackets
        fields = stat[stat.rindex(")") + 1 :].split()  # state, ppid, pgrp, ...
        out.append((int(entry), name, int(fields[1]), int(fields[2])))
    return out


def process_tree() -> dict[int, list[int]]:
    """Every process's children (pid -> child pids)."""
    tree: dict[int, list[int]] = {}
    for pid, _name, ppid, _pgid in processes():
        tree.setdefault(ppid, []).append(pid)
    return tree


def descendants(pid: int, tree: dict[int, list[int]]) -> list[int]:
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        todo.extend(tree.get(p, []))
    return out


def lower(pids: list[int], nice: int = OTHERS_NICE) -> int:
    """Every thread of ``pids`` on the normal policy at ``nice`` or lower; the number of changes."""
    changed = 0
    for pid in pids:
        try:
            tids = [int(t) for t in os.listdir(f"/proc/{pid}/task")]
        except OSError:
            continue  # ended meanwhile
        for tid in tids:
            try:
                if is_real_time(tid):
                    # a library switched it to real time (SVT-AV1 does, as root: common/scheduling.py):
                    # ahead of every normal thread whatever its nice value
                    os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
                    changed += 1
                if os.getpriority(os.PRIO_PROCESS, tid) < nice:  # Linux: a thread id names one thread
                    os.setpriority(os.PRIO_PROCESS, tid, nice)
                    changed += 1
            except OSError:
                continue  # ended meanwhile, or not ours
    return changed


def lower_other_workers(folder: Path) -> int:
    """Lower every worker of this run that runs no lane, and all it started; the number of threads changed."""
    me = os.getpid()
    others = []
    for path in folder.glob("*.pid"):
        if runs_a_lane(folder, path.stem):
            continue  # a lane's worker: realtime tests run there (it lowers itself when its lane is done)
        try:
            pid = int(path.read_text())
        except (OSError, ValueError):
            continue
        if pid != me:
            others.append(pid)
    if not others:
        return 0
    tree = process_tree()
    return lower([p for pid in others for p in descendants(pid, tree)])


@contextlib.contextmanager
def turn(folder: Path, alone: bool) -> Iterator[None]:
    """A realtime test's turn: shared with the other lane's test, or (``alone``: a test whose threads
    must keep pace with a device's bytes, as a gauge's stream) with none, waiting for the other lane's
    test in progress to end (the lanes end minutes before the other workers, so this costs no time)."""
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "realtime.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX if alone else fcntl.LOCK_SH)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def runs_a_lane(folder: Path, worker: str) -> bool:
    return (folder / f"{worker}.lane").exists()


_lowered_myself = False


def lower_myself() -> int:
    """A lane's worker going on with other tests: itself and all it started to ``OTHERS_NICE``, once
    (what it starts later inherits its nice value); the number of threads changed."""
    global _lowered_myself
    if _lowered_myself:
        return 0
    _lowered_myself = True
    return lower(descendants(os.getpid(), process_tree()))


def lanes(nodeids: set[str], count: int) -> dict[str, str]:
    """Each realtime test's lane (nodeid -> unit name): whole files, the longest first into the lane
    with the least time so far (FILE_SECONDS)."""
    files: dict[str, list[str]] = {}
    for nodeid in sorted(nodeids):
        files.setdefault(nodeid.split("::", 1)[0], []).append(nodeid)
    weight = lambda f: FILE_SECONDS.get(Path(f).name, DEFAULT_S)  # noqa: E731
    totals = [0.0] * count
    out = {}
    for f in sorted(files, key=lambda f: (-weight(f), f)):
        lane = totals.index(min(totals))
        totals[lane] += weight(f)
        out.update((nodeid, f"{UNIT}-{lane}") for nodeid in files[f])
    return out


def write_collected(folder: Path, worker: str, nodeids: list[str]) -> None:
    """Note the realtime tests this worker collected (before it reports its collection)."""
    folder.mkdir(parents=True, exist_ok=True)
    part = folder / f"{worker}.realtime-part"
    part.write_text("\n".join(nodeids))
    part.replace(folder / f"{worker}.realtime")


def read_collected(folder: Path) -> set[str]:
    return {n for path in folder.glob("*.realtime") for n in path.read_text().splitlines() if n}


def _without_group(nodeid: str) -> str:
    """A node id without the ``@group`` suffix an xdist that can rename ids again would add."""
    return nodeid.rsplit("@", 1)[0] if nodeid.rfind("@") > nodeid.rfind("]") else nodeid


class RealtimeFirst(LoadScopeScheduling):
    """Each test its own unit, except the realtime tests: one unit per lane, handed out before any
    other unit, one lane per worker (the lanes' workers are marked in ``folder`` before any test
    runs)."""

    def __init__(self, config, log, folder: Path):
        super().__init__(config, log)
        self.folder = folder
        self.lane_of: dict[str, str] = {}
        self.lanes_first = False

    def schedule(self) -> None:
        if self.collection is None:  # the first call: every worker has collected (and written)
            count = max(1, min(LANES, len(self.nodes) - 1))
            self.lane_of = lanes(read_collected(self.folder), count)
            used = len(set(self.lane_of.values()))
            # the lanes go to the first nodes (_assign_work_unit below): marked before any test starts
            for node in self.nodes[:used]:
                (self.folder / f"{node.gateway.id}.lane").write_text("")
        super().schedule()

    def _assign_work_unit(self, node) -> None:
        if not self.lanes_first:  # the first call, in the initial distribution: the lanes before any other unit
            for unit in sorted((u for u in self.workqueue if u.startswith(UNIT + "-")), reverse=True):
                self.workqueue.move_to_end(unit, last=False)
            self.lanes_first = True
        if self.workqueue and next(iter(self.workqueue)).startswith(UNIT + "-"):
            (self.folder / f"{node.gateway.id}.lane").write_text("")
        super()._assign_work_unit(node)

    def _split_scope(self, nodeid: str) -> str:
        return self.lane_of.get(_without_group(nodeid), nodeid)
