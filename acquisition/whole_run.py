"""A run file written whole or not at all: what ``dataset merge`` and ``dataset import`` write
(and ``whole_folder``, a folder likewise: what ``dataset export`` writes).

``whole_run(out, header, ...)`` checks that ``out``'s folder exists (naming it when not) and that
``out`` does not, takes ``out``'s writer lock, and hands out a RunWriter on ``RUN.h5.writing-PID``
beside it. When the block ends without an error the file is closed, read back through the verified
reader (a file every reader would refuse is never put in place), fsynced and renamed to ``out``;
when it raises, the temporary file is removed and ``out`` never appears, so a refused merge or
import leaves nothing behind.

SIGTERM and SIGHUP (kill, a closed terminal) are turned into an exception while the file is written,
as SIGINT is (rig/interruption.py's ``SignalsAsExceptions``), so they remove the temporary file and
both locks too; the removal itself runs with signals held, in a ``finally`` that a failing close
cannot skip. Only ``kill -9`` (or a power cut) can leave the temporary file, which the next writer
of ``out`` removes (acquisition/run_storage.py's TEMP_MARKS).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from acquisition.run_reader import RunReader
from acquisition.run_storage import fsync_path, remove_stale_temps, temp_path
from acquisition.run_writer import RunHeader, RunWriter
from acquisition.writer_lock import RunFileError
from rig.interruption import MotionInterrupted, SignalsAsExceptions

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
    with SignalsAsExceptions() as signals:
        lock = RunWriter.claim(out)
        tmp = temp_path(out, MARK)
        writer: RunWriter | None = None
        try:
            remove_stale_temps(out)
            writer = RunWriter.create(tmp, header, frame_shape, object_image, reference_frame, codec=codec)
            yield writer
            writer.close()
            _read_back(tmp, out, what)
            fsync_path(tmp)
            os.replace(tmp, out)
        except OSError as exc:
            raise RunFileError(f"{out}: cannot be written ({exc.strerror or exc}); nothing was left there") from None
        finally:
            with _held(signals):
                _remove(writer, tmp)
                lock.release()
        _raise_held(signals)


@contextmanager
def whole_folder(out: Path, what: str) -> Iterator[Path]:
    """A temporary folder beside ``out`` (``.OUT.{what}ing-PID``) that is renamed to ``out`` only if
    the block completes, and removed whatever happens (``dataset export``): an error, SIGTERM, SIGHUP
    or Ctrl-C leave nothing, as for a run file. ``what`` names the command in messages."""
    tmp = out.with_name(f".{out.name}.{what}ing-{os.getpid()}")
    with SignalsAsExceptions() as signals:
        try:
            yield tmp
            os.replace(tmp, out)
        except OSError as exc:
            raise RunFileError(
                f"--out {out}: cannot write the {what} ({exc.strerror or exc}); nothing was left there"
            ) from None
        finally:
            with _held(signals):
                shutil.rmtree(tmp, ignore_errors=True)
        _raise_held(signals)


@contextmanager
def _held(signals: SignalsAsExceptions) -> Iterator[None]:
    """The block (a clean-up) with signals only noted: a second one must not cut it short."""
    signals.holding = True
    try:
        yield
    finally:
        signals.holding = False


def _raise_held(signals: SignalsAsExceptions) -> None:
    """A signal that came during the clean-up, raised now that it is done."""
    if signals.held:
        raise MotionInterrupted(signals.held)


def _remove(writer: RunWriter | None, tmp: Path) -> None:
    """Close ``writer`` if it is open (releasing its lock) and remove ``tmp``, whatever the close says."""
    try:
        if writer is not None and writer.f.id.valid:
            writer.close()
    except RunFileError:
        pass  # the file is being thrown away: a failed close changes nothing
    finally:
        if writer is not None:
            writer.lock.release()
        tmp.unlink(missing_ok=True)


def _read_back(tmp: Path, out: Path, what: str) -> None:
    """RunFileError unless the finished file opens through the verified reader, as every command reads it."""
    try:
        RunReader.open(tmp).close()
    except RunFileError as exc:
        problem = str(exc).removeprefix(f"{tmp}: ")
        raise RunFileError(
            f"{out}: {what} wrote a file that every reader would refuse ({problem}); nothing was left there"
        ) from None
