"""A run file written whole or not at all: what ``dataset merge`` and ``dataset import`` write.

``whole_run(out, header, ...)`` checks that ``out``'s folder exists (naming it when not) and that
``out`` does not, takes ``out``'s writer lock, and hands out a RunWriter on ``RUN.h5.writing-PID``
beside it. When the block ends without an error the file is closed, fsynced and renamed to ``out``;
when it raises, the temporary file is removed and ``out`` never appears, so a refused merge or
import leaves nothing behind. A crash leaves at most the temporary file, which the next writer of
``out`` removes (acquisition/run_storage.py's TEMP_MARKS).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from acquisition.run_storage import fsync_path, remove_stale_temps, temp_path
from acquisition.run_writer import RunHeader, RunWriter
from acquisition.writer_lock import RunFileError

MARK = ".writing-"


def check_new_output(out: Path, what: str) -> None:
    """``out`` must not exist and its folder must: RunFileError naming which, and what to do."""
    if out.exists():
        raise RunFileError(
            f"{out}: exists; {what} writes a new run file: choose another --out, or delete {out.name} first"
        )
    if not out.parent.is_dir():
        raise RunFileError(f"{out}: the folder {out.parent} does not exist; create it first (mkdir -p {out.parent})")


@contextmanager
def whole_run(
    out: str | Path,
    header: RunHeader,
    frame_shape: tuple[int, int, int],
    object_image: np.ndarray,
    reference_frame: np.ndarray,
    *,
    what: str,
    codec: str | None = None,
) -> Iterator[RunWriter]:
    """A writer whose file appears at ``out`` only if the block completes (module docstring);
    ``what`` names the command in messages."""
    out = Path(out)
    check_new_output(out, what)
    lock = RunWriter.claim(out)
    try:
        remove_stale_temps(out)
        tmp = temp_path(out, MARK)
        writer = RunWriter.create(tmp, header, frame_shape, object_image, reference_frame, codec=codec)
        try:
            yield writer
            writer.close()
            fsync_path(tmp)
            os.replace(tmp, out)
        except OSError as exc:
            raise RunFileError(f"{out}: cannot be written ({exc.strerror or exc}); nothing was left there") from None
        finally:
            if writer.f.id.valid:
                writer.close()
            tmp.unlink(missing_ok=True)
    finally:
        lock.release()
