"""``--resume``: reopen a run to append to it, after verifying every chunk it has committed.

``reopen(path)`` (what ``RunWriter.reopen`` and so the executor call) takes the writer lock and
verifies the file read-only, through the bounded SWMR reader every command uses
(acquisition/hdf5_open.py: a damaged file fails within a second), before it opens it for appending:

* the layout against the schema table, the root attributes against their checksum
  (acquisition/attr_checksum.py), the checksum filters (on every growing dataset or on none), the
  status, the object image and the reference frame: the checks of the verified reader and
  ``dataset validate`` (acquisition/run_checks.py);
* every row chunk, read through HDF5 (checksums), and the rows' values as every reader checks them
  (finite, time increasing, the capture grid contiguous, phases within the file's list, one row per
  frame once closed);
* every frame chunk and every chunk of the full-rate stream against its Fletcher-32 checksum
  (acquisition/chunk_checksum.py), a chunk index that cannot be read included.

A run whose writer crashed (status still ``running``) may end in frames and stream rows that never
reached the disk: that tail is dropped, as the crash left it uncounted (acquisition/crash_tail.py).
Anything else that fails is refused in one line naming the file, the dataset and the frame.

Only then is the file opened for appending (a crashed writer's file first copied into a clean one,
acquisition/run_storage.py's ``recover``) and switched into SWMR write mode, in which HDF5 would
retry a damaged piece of metadata without end: nothing it reads there is unverified.
"""

from __future__ import annotations

import datetime as dt
import logging
from pathlib import Path

import h5py

from acquisition import attr_checksum
from acquisition import schema as S
from acquisition.chunk_checksum import ChunkIndexError
from acquisition.crash_tail import frames_kept, stream_kept
from acquisition.frame_checks import check_frames
from acquisition.frame_identity import stream_wrong
from acquisition.hdf5_open import check_complete, open_append, open_swmr_read
from acquisition.run_checks import (
    checksum_findings,
    first_line,
    image_findings,
    metadata_problem,
    read_rows,
    row_count_findings,
    row_findings,
    status_findings,
)
from acquisition.run_layout import decode_phases, layout_problems
from acquisition.run_storage import chunked, frames_codec, recover, remove_stale_temps
from acquisition.writer_lock import RunFileError, WriterLock

log = logging.getLogger("acquisition")


def reopen(path: str | Path, writer_type, supersede=None):
    """The run at ``path`` open for appending as a ``writer_type`` (acquisition/run_writer.py's
    RunWriter, which calls this from ``RunWriter.reopen``; passed in so that the writer's module
    and this one do not import each other). RunLocked while another process writes it;
    RunFileError naming the file, dataset and frame when it is not sound (module docstring).

    ``supersede(frames, attrs) -> (keep, why)``: given the frames the file keeps and its root attributes
    (verified; the caller may refuse the file here, before anything changes), how many stay (the
    rest were taken by a level the resume re-does: acquisition/executor.py) and why. Those after
    ``keep`` are moved into ``superseded/retake-N`` (frames, rows and digests, with ``why``) before
    the file is opened for appending, and the writer's ``retake`` is N (0 when none moved)."""
    path = Path(path)
    lock = WriterLock.acquire(path)
    try:
        stale = remove_stale_temps(path)
        if not path.exists():
            detail = f" (a crash interrupted its creation; removed {', '.join(p.name for p in stale)})" if stale else ""
            raise RunFileError(f"{path}: no such run file to resume{detail}; start a new run")
        if not path.is_file():
            raise RunFileError(f"{path}: not a regular file, expected a run file (.h5); cannot resume it")
        problem = check_complete(path)
        if problem:
            raise RunFileError(f"{path}: {problem}; cannot resume it")
        frames, stream_rows, attrs = _committed(path)
        keep, why = supersede(frames, attrs) if supersede is not None else (frames, "")
        f = _open_for_append(path)
        try:
            retake = 0
            if keep < frames:  # before SWMR mode, which forbids new groups and datasets
                retake = _move_superseded(f, keep, frames, why)
                frames = keep
            f.swmr_mode = True
            writer = writer_type(f, path, lock)
            writer.retake = retake
            writer.n, writer._stream_n = frames, stream_rows
            writer._truncate_to(frames)
            writer.set_status("running", "")  # being written again: readers treat its end as uncommitted
        except BaseException:
            f.close()
            raise
        return writer
    except BaseException:
        lock.release()
        raise


def _move_superseded(f: h5py.File, lo: int, hi: int, why: str) -> int:
    """Frames ``lo``..``hi``-1 with their rows and digests copied into a new ``superseded/retake-N``
    group (kept, checksummed, compressed as the frames are), which says why; returns N. The caller
    then shrinks the run's own datasets to ``lo``."""
    group = f.require_group(S.SUPERSEDED)
    number = len(group) + 1
    g = group.create_group(f"retake-{number}")
    g.attrs["first_capture_index"] = lo
    g.attrs["frames"] = hi - lo
    g.attrs["why"] = why
    g.attrs["superseded_utc"] = dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")
    frames = f[S.FRAMES]
    shape = frames.shape[1:]
    copy = g.create_dataset(
        S.FRAMES, (hi - lo, *shape), dtype=frames.dtype, **chunked((1, *shape), codec=frames_codec(f))
    )
    for i in range(lo, hi):  # one frame at a time: a level holds hundreds
        copy[i - lo] = frames[i]
    for name in [fl.path for fl in S.PER_FRAME_FIELDS] + [S.FRAME_DIGEST]:
        if name in f:
            g.create_dataset(name, data=f[name][lo:hi], fletcher32=True)
    return number


def _refuse(path: Path, problem: str) -> RunFileError:
    return RunFileError(f"{path}: {problem}; the file is damaged, cannot resume it")


def _committed(path: Path) -> tuple[int, int, dict]:
    """(frames, stream rows, root attributes) the file keeps, verified read-only (module docstring)."""
    try:
        f = open_swmr_read(path)
    except (OSError, RuntimeError, KeyError) as exc:
        raise RunFileError(f"{path}: cannot open for appending: {first_line(exc)}") from None
    with f:
        try:
            return (*_verify(path, f), dict(f.attrs))
        except ChunkIndexError as exc:  # a dataset whose chunks cannot be located
            raise _refuse(path, str(exc)) from None
        except (OSError, RuntimeError, KeyError, ValueError) as exc:  # damage beyond what the checks expect
            raise _refuse(path, f"unreadable ({first_line(exc)})") from None


def _verify(path: Path, f: h5py.File) -> tuple[int, int]:
    damaged = metadata_problem(f)
    problems = [damaged] if damaged else layout_problems(f)
    if problems:
        raise RunFileError(f"{path}: cannot resume: {'; '.join(problems)}")
    sound = {fl.path for fl in S.FIELDS if fl.path in f}
    problems = [attr_checksum.problem(f)[0]] + checksum_findings(f, sound)[0]
    status, _, found = status_findings(f, sound)
    problems += found
    frames = f[S.FRAMES]
    problems += row_count_findings(f, sound, frames.shape[0], status)
    problems = [p for p in problems if p]
    if problems:
        raise _refuse(path, problems[0])
    crashed = status == "running"
    n = frames.shape[0]
    rows, problems = read_rows(f, [fl.path for fl in S.PER_FRAME_FIELDS if fl.path in sound], n)
    if problems:
        raise _refuse(path, problems[0])
    try:
        kept, problem = frames_kept(frames, n, crashed)
        if not problem:  # each frame in its place too (acquisition/frame_identity.py): the same tail rule
            check = check_frames(f, rows, kept)
            tail = check.tail_from(kept)
            if check.bad and (min(check.bad) < tail or not crashed):
                problem = check.findings()[0]
            kept = tail
    except ChunkIndexError as exc:
        raise _refuse(path, f"{S.FRAMES}: {exc}") from None
    if problem:
        raise _refuse(path, problem)
    for i in range(n - 1, kept - 1, -1):
        log.warning("%s: frame %d never reached the disk; dropped", path, i)
    findings = row_findings({k: v[:kept] for k, v in rows.items()}, kept, len(decode_phases(f)))
    findings += image_findings(f, sound)[1]
    if findings:
        raise _refuse(path, findings[0])
    return kept, _stream_rows(path, f, crashed)


def _stream_rows(path: Path, f: h5py.File, crashed: bool) -> int:
    d = f.get(S.WRENCH_STREAM)
    if d is None or d.shape[0] == 0:
        return 0
    try:
        kept, problem = stream_kept(d, crashed)
    except ChunkIndexError as exc:
        raise _refuse(path, f"{S.WRENCH_STREAM}: {exc}") from None
    if problem:
        raise _refuse(path, problem)
    wrong = stream_wrong(f, d[:kept]) if kept else []
    if wrong:
        if not crashed or wrong != list(range(wrong[0], kept)):
            raise _refuse(
                path, f"{S.WRENCH_STREAM}[{wrong[0]}]: not the row written at this index (its digest differs)"
            )
        kept = wrong[0]  # rows whose digests never reached the disk: a crashed writer's tail
    if kept < d.shape[0]:
        log.warning("%s: %s rows %d.. never reached the disk; dropped", path, S.WRENCH_STREAM, kept)
    return kept


def _open_for_append(path: Path) -> h5py.File:
    try:
        return open_append(path)
    except (OSError, RuntimeError) as exc:
        first = exc
    log.info("%s: recovering after a crash (%s)", path, first_line(first))
    try:  # a crashed SWMR writer leaves a flag that only a copy clears
        recover(path)
        return open_append(path)
    except (OSError, RuntimeError, KeyError) as exc:
        raise RunFileError(f"{path}: cannot recover it for appending: {first_line(exc)}") from None
