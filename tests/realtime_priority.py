"""Realtime tests first in the CPU, the other test processes after them (Linux scheduling priority).

The suite runs on several processes (pytest-xdist). Tests marked ``realtime`` assert what happens at a
moment of real time, so a loaded machine must not delay them. They all run in one worker, one after the
other (one work unit of the scheduler below), and while they run the other workers and everything they started (threads,
commands, simulators, browsers) are lowered to nice ``OTHERS_NICE``: the kernel then gives the realtime
test the cores it asks for at once, and the other workers the rest, instead of stopping them.

Only ever raising other processes' nice value needs no privilege (lowering it back would), so the other
workers stay lowered for the rest of the run; none of their tests asserts real time.

The unit: xdist's own ``--dist loadgroup`` groups by renaming node ids, which pytest 9.2 no longer
lets it do (pytest-dev/pytest-xdist#1386: the groups are silently ignored). So each worker writes the
realtime tests it collected to the run's folder, and the scheduler (``RealtimeFirst``, installed by
tests/conftest.py for ``--dist loadgroup``) reads them and makes them one unit, the largest, which
xdist hands out first.
"""

from __future__ import annotations

import os
from pathlib import Path

from xdist.scheduler import LoadScopeScheduling

OTHERS_NICE = 19  # the lowest priority: CFS weight 15 against a default task's 1024
UNIT = "realtime"  # the scheduler's name for the unit of every realtime test


def register_worker(folder: Path, worker: str) -> None:
    """Note this worker's pid in ``folder`` (the run's shared temporary folder); ``worker``: its id (gw0...)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{worker}.pid").write_text(str(os.getpid()))


def _children() -> dict[int, list[int]]:
    """Every process's children, from /proc (pid -> child pids)."""
    tree: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])  # after the command name, which may hold spaces
        tree.setdefault(ppid, []).append(int(entry))
    return tree


def descendants(pid: int, tree: dict[int, list[int]]) -> list[int]:
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        todo.extend(tree.get(p, []))
    return out


def lower(pids: list[int], nice: int = OTHERS_NICE) -> int:
    """Set every thread of ``pids`` to at least ``nice``; the number of threads changed."""
    changed = 0
    for pid in pids:
        try:
            tids = [int(t) for t in os.listdir(f"/proc/{pid}/task")]
        except OSError:
            continue  # ended meanwhile
        for tid in tids:
            try:
                if os.getpriority(os.PRIO_PROCESS, tid) < nice:  # Linux: a thread id names one thread
                    os.setpriority(os.PRIO_PROCESS, tid, nice)
                    changed += 1
            except OSError:
                continue  # ended meanwhile, or not ours
    return changed


def lower_other_workers(folder: Path) -> int:
    """Lower every other worker of this run and all it started; the number of threads changed."""
    me = os.getpid()
    others = []
    for path in folder.glob("*.pid"):
        try:
            pid = int(path.read_text())
        except (OSError, ValueError):
            continue
        if pid != me:
            others.append(pid)
    if not others:
        return 0
    tree = _children()
    return lower([p for pid in others for p in descendants(pid, tree)])


def write_collected(folder: Path, worker: str, nodeids: list[str]) -> None:
    """Note the realtime tests this worker collected (before it reports its collection)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{worker}.realtime"
    path.with_suffix(".part").write_text("\n".join(nodeids))
    path.with_suffix(".part").replace(path)


def read_collected(folder: Path) -> set[str]:
    return {n for path in folder.glob("*.realtime") for n in path.read_text().splitlines() if n}


def _without_group(nodeid: str) -> str:
    """A node id without the ``@group`` suffix an xdist that can rename ids again would add."""
    return nodeid.rsplit("@", 1)[0] if nodeid.rfind("@") > nodeid.rfind("]") else nodeid


class RealtimeFirst(LoadScopeScheduling):
    """Each test its own unit, except the realtime tests: one unit, which as the largest
    (``--loadscope-reorder``, xdist's default) goes first, to one worker."""

    def __init__(self, config, log, folder: Path):
        super().__init__(config, log)
        self.folder = folder
        self.realtime: set[str] = set()

    def schedule(self) -> None:
        if self.collection is None:  # the first call: every worker has collected (and written)
            self.realtime = read_collected(self.folder)
        super().schedule()

    def _split_scope(self, nodeid: str) -> str:
        return UNIT if _without_group(nodeid) in self.realtime else nodeid
