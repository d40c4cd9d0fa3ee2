"""``--resume``: reopen a run to append to it, after verifying every chunk it has committed.

``reopen(path)`` (what ``RunWriter.reopen`` and so the executor call) takes the writer lock,
recovers a file whose writer crashed (HDF5 keeps its "being written" flag: a clean copy clears
it, acquisition/run_storage.py), checks the layout against the schema table, and then verifies
what the file holds before a single frame is appended:

* every row chunk, read through HDF5 (checksums), and the rows' values as every reader checks
  them (acquisition/run_checks.py: finite, time increasing, the capture grid contiguous, phases
  within the file's list, one row per frame once closed);
* every frame chunk against its Fletcher-32 checksum (acquisition/chunk_checksum.py).

A run whose writer crashed (status still ``running``) may end in frames that never reached the
disk (a chunk never written, or one cut short): those trailing frames, and stream rows past the
first that never reached the disk, are dropped, as the crash left them uncounted. Anything else
that fails — a damaged frame followed by sound ones, any damage in a run that was closed
(complete, aborted, interrupted), a damaged row chunk — is refused in one line naming the file,
the dataset and the frame: appending to a damaged run would bury the damage under new frames.
"""

from __future__ import annotations

import logging
from pathlib import Path

import h5py
import numpy as np

from acquisition import schema as S
from acquisition.chunk_checksum import bad_chunks
from acquisition.hdf5_open import check_complete, open_swmr_read
from acquisition.run_checks import (
    first_line,
    metadata_problem,
    read_rows,
    read_stream,
    row_count_findings,
    row_findings,
    text_of,
)
from acquisition.run_layout import layout_problems
from acquisition.run_storage import STREAM_BLOCK, recover, remove_stale_temps
from acquisition.writer_lock import RunFileError, WriterLock

log = logging.getLogger("acquisition")


def reopen(path: str | Path, writer_type):
    """The run at ``path`` open for appending as a ``writer_type`` (acquisition/run_writer.py's
    RunWriter, which calls this from ``RunWriter.reopen``; passed in so that the writer's module
    and this one do not import each other). RunLocked while another process writes it;
    RunFileError naming the file, dataset and frame when it is not sound (module docstring)."""
    path = Path(path)
    lock = WriterLock.acquire(path)
    try:
        stale = remove_stale_temps(path)
        if not path.exists():
            detail = f" (a crash interrupted its creation; removed {', '.join(p.name for p in stale)})" if stale else ""
            raise RunFileError(f"{path}: no such run file to resume{detail}; start a new run")
        problem = check_complete(path)
        if problem:
            raise RunFileError(f"{path}: {problem}; cannot resume it")
        f = _open_for_append(path)
        damaged = metadata_problem(f)
        problems = [damaged] if damaged else layout_problems(f)
        if problems:
            f.close()
            raise RunFileError(f"{path}: cannot resume: {'; '.join(problems)}")
        f.swmr_mode = True
        writer = writer_type(f, path, lock)
        try:
            _verify_committed(writer)
        except BaseException:
            f.close()
            raise
        return writer
    except BaseException:
        lock.release()
        raise


def _open_for_append(path: Path) -> h5py.File:
    try:
        return h5py.File(path, "r+", libver="latest")
    except OSError as exc:
        first = exc
    try:  # a crashed SWMR writer leaves a flag that only a copy clears; it must still read
        open_swmr_read(path).close()
    except (OSError, RuntimeError, KeyError) as exc:
        raise RunFileError(f"{path}: cannot open for appending: {first_line(exc)}") from None
    log.info("%s: recovering after a crash (%s)", path, first_line(first))
    try:
        recover(path)
        return h5py.File(path, "r+", libver="latest")
    except (OSError, RuntimeError, KeyError) as exc:
        raise RunFileError(f"{path}: cannot recover it for appending: {first_line(exc)}") from None


def _refuse(writer, problem: str) -> RunFileError:
    return RunFileError(f"{writer.path}: {problem}; the file is damaged, cannot resume it")


def _verify_committed(writer) -> None:
    """Verify what the file holds and keep the frames that reached the disk (module docstring)."""
    f, path = writer.f, writer.path
    status, problem = text_of(f, S.STATUS)
    if problem:
        raise _refuse(writer, problem)
    crashed = status == "running"
    frames = writer._frames
    n = min([frames.shape[0]] + [d.shape[0] for d in writer._rows.values()])
    count = row_count_findings(f, set(writer._rows) | {S.FRAMES}, frames.shape[0], status)
    if count:
        raise _refuse(writer, count[0])
    rows, problems = read_rows(f, list(writer._rows), n)
    if problems:
        raise _refuse(writer, problems[0])
    damaged = list(bad_chunks(frames, n))
    if damaged:
        tail = n
        for lo, hi, _ in reversed(damaged):  # the run of damaged frames that ends the file
            if hi != tail - 1:
                break
            tail = lo
        inside = [d for d in damaged if d[0] < tail]
        if inside or not crashed:
            lo, _, what = (inside or damaged)[0]
            raise _refuse(writer, f"{S.FRAMES}[{lo}]: {what}")
        for i in range(n - 1, tail - 1, -1):
            log.warning("%s: frame %d never reached the disk; dropped", path, i)
        n = tail
    findings = row_findings({k: v[:n] for k, v in rows.items()}, n, len(writer.phases))
    if findings:
        raise _refuse(writer, findings[0])
    writer.n = n
    writer._stream_n = _stream_kept(writer, crashed)
    writer._truncate_to(n)


def _stream_kept(writer, crashed: bool) -> int:
    """Rows of the stream to keep: all of a closed run's (verified: damage is refused); a crashed
    run's up to the first that never reached the disk (a chunk never written reads as zeros, time
    going back; a cut one fails its checksum)."""
    stream = writer._stream
    if stream is None or stream.shape[0] == 0:
        return 0
    if not crashed:
        _, findings = read_stream(writer.f, S.WRENCH_STREAM)
        if findings:
            raise _refuse(writer, findings[0])
        return stream.shape[0]
    try:
        t = stream[:, 0]
    except (OSError, RuntimeError):  # locate the damaged chunk: keep the rows before it
        t = np.concatenate([_read_or_nan(stream, i) for i in range(0, stream.shape[0], STREAM_BLOCK)])
    ok = np.isfinite(t) & np.concatenate([[True], np.diff(t) >= 0])
    kept = int(np.argmin(ok)) if not ok.all() else len(t)
    if kept < len(t):
        log.warning("%s: %s rows %d.. never reached the disk; dropped", writer.path, S.WRENCH_STREAM, kept)
    return kept


def _read_or_nan(stream: h5py.Dataset, start: int) -> np.ndarray:
    stop = min(start + STREAM_BLOCK, stream.shape[0])
    try:
        return stream[start:stop, 0]
    except (OSError, RuntimeError):
        return np.full(stop - start, np.nan)
