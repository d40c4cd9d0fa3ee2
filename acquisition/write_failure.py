"""Why a run file's write failed, in words, and the space check that prevents most failures.

A write HDF5 starts and the disk refuses is rolled back by the writer
(``RunWriter._fail``), except when the file may not grow at all (a file-size limit,
EFBIG): HDF5 then cannot extend the file to the space it allocated, no flush succeeds
again, and the library crashed at exit (rc 139). So before each frame the writer checks
both the free space and the process's file-size limit here first.
"""

from __future__ import annotations

import errno
import os
import re
import resource
from pathlib import Path

SPACE_MARGIN_BYTES = 1 << 20  # metadata a flush may add beside the frame itself


def _first_line(exc: BaseException) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def errno_of(exc: BaseException) -> int | None:
    """OSError's errno, or the one h5py's RuntimeError quotes ("errno = 28, ...")."""
    if isinstance(exc, OSError) and exc.errno:
        return exc.errno
    found = re.search(r"errno = (\d+)", str(exc))
    return int(found.group(1)) if found else None


def space_shortfall(path: Path, need_bytes: int) -> OSError | None:
    """The error a write of ``need_bytes`` more into ``path`` would meet (ENOSPC, EFBIG), or None."""
    try:
        st = os.statvfs(path.parent)
        size = path.stat().st_size
    except OSError:
        return None
    free = st.f_bavail * st.f_frsize
    if free < need_bytes:
        return OSError(errno.ENOSPC, f"{free:,} bytes free in {path.parent}")
    limit, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    if limit != resource.RLIM_INFINITY and size + need_bytes > limit:
        return OSError(errno.EFBIG, f"this process may write files up to {limit:,} bytes (ulimit -f)")
    return None


def describe_failure(exc: BaseException, i: int) -> tuple[str, str]:
    """(what, the run's reason) for frame ``i`` failing with ``exc``, e.g. ("disk full",
    "disk full: frame 812 could not be written (No space left on device); frames 0-811 are kept")."""
    code = errno_of(exc)
    what = {
        errno.ENOSPC: "disk full",
        errno.EDQUOT: "disk quota exceeded",
        errno.EFBIG: "file too large (filesystem or process file-size limit)",
    }.get(code or 0, "write failed")
    detail = os.strerror(code) if code else _first_line(exc)
    if isinstance(exc, OSError) and exc.strerror and exc.strerror != detail:
        detail = f"{detail}: {exc.strerror}"
    kept = f"frames 0-{i - 1} are kept" if i else "no frame was written"
    return what, f"{what}: frame {i} could not be written ({detail}); {kept}"
