"""One writer per run file: an flock on the ``RUN.h5.lock`` sidecar.

HDF5's own file lock is dropped once a writer enters SWMR mode (so that readers can
follow the run), which is why it cannot keep a second writer or ``--resume`` out.
The kernel releases an flock when its process dies, kill -9 included, so on a local
disk a lock can never outlive its writer; the sidecar file left behind by a crash
holds no lock and is reused. Only on a network filesystem that loses lock state can
a lock look held with its writer gone: then deleting the sidecar clears it.
"""

from __future__ import annotations

import fcntl
import os
import socket
from pathlib import Path

from common.errors import ToolError


class RunFileError(ToolError):
    """A run file is missing, not HDF5, damaged, or not what was expected; names the file."""


class RunLocked(ToolError):
    """Another live process writes this run file; names its pid and host."""


def lock_path(run_path: Path) -> Path:
    return run_path.with_name(run_path.name + ".lock")


def _holder(path: Path) -> str:
    try:
        text = path.read_text().strip()
    except OSError:
        text = ""
    return text or "a process that has not written its pid yet"


class WriterLock:
    """Held by the one process that writes ``run_path``; ``release`` removes the sidecar."""

    def __init__(self, run_path: Path, fd: int):
        self.run_path = run_path
        self.path = lock_path(run_path)
        self._fd: int | None = fd

    @classmethod
    def acquire(cls, run_path: str | Path) -> "WriterLock":
        """Take the lock without waiting; RunLocked names the holder, RunFileError an unwritable folder."""
        run_path = Path(run_path)
        path = lock_path(run_path)
        while True:
            try:
                fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise RunFileError(f"{run_path}: cannot create its writer lock {path} ({exc.strerror})") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                holder = _holder(path)
                raise RunLocked(
                    f"{run_path}: being written by {holder} (lock {path}); wait for that run to end or stop it. "
                    f"The lock dies with its process, so it cannot be stale on a local disk; on a network "
                    f"filesystem, if that process is gone, delete {path}"
                ) from None
            # The previous holder may have removed the sidecar between our open and our
            # flock: then we locked an unlinked file, and must lock the one at the path.
            try:
                same = os.stat(path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"pid {os.getpid()} on host {socket.gethostname()}\n".encode())
        return cls(run_path, fd)

    @property
    def held(self) -> bool:
        return self._fd is not None

    def release(self) -> None:
        if self._fd is None:
            return
        try:
            os.unlink(self.path)  # while still locked, so nobody else holds this inode
        except OSError:
            pass  # already gone or a read-only folder: a lock-less sidecar is harmless
        os.close(self._fd)
        self._fd = None


def live_writer(run_path: str | Path) -> str | None:
    """Who holds the lock of ``run_path`` ("pid N on host H"), or None when nobody does."""
    path = lock_path(Path(run_path))
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return _holder(path)
    finally:
        os.close(fd)
    return None
