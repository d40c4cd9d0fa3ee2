"""``dataset compact``: rewrite a run file with its frames compressed, verified first.

Files written before compression (or before checksums) store frames raw: 1.14 GB for
one sphere10mm run. ``compact`` copies such a file into ``RUN.h5.compacting-PID`` beside
it, every growing dataset created as the writer creates it (``run_storage.chunked``:
compressed frames, Fletcher-32 everywhere), then reads the copy back and compares it
with the original frame by frame, row by row, dataset by dataset and attribute by
attribute, and only then renames it over the original. The original is opened through the verified
reader (acquisition/run_reader.py: schema, attributes, rows and images); its frames are verified by
the copy's own read of each (HDF5 checks every chunk's checksum), so a damaged frame stops the copy,
which is removed. A file whose frames are compressed already is left as it is without reading a
frame (``dataset validate`` checks them). It holds the run's writer lock
throughout, so a run being written (or resumed) is refused and cannot start meanwhile.
Any failure removes the copy and leaves the original as it was.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from acquisition import schema as S
from acquisition.frame_checks import check_frames
from acquisition.frame_identity import FRAME_DIGEST_BYTES, frame_digest, key_of, row_bytes, stored_chunk
from acquisition.hdf5_open import check_complete
from acquisition.run_reader import RunReader
from acquisition.run_storage import (
    ROW_BLOCK,
    STREAM_BLOCK,
    chunked,
    frames_codec,
    fsync_path,
    remove_stale_temps,
    temp_path,
)
from acquisition.writer_lock import RunFileError, WriterLock
from rig.interruption import SignalsAsExceptions

ROW_FIELDS = {f.path: ROW_BLOCK for f in S.PER_FRAME_FIELDS} | {f.path: STREAM_BLOCK for f in S.STREAM_FIELDS}


@dataclass(frozen=True)
class Compacted:
    path: Path
    frames: int
    bytes_before: int
    bytes_after: int  # equal to bytes_before when nothing was done
    done: bool  # False: the frames were compressed already


def frames_compressed(f: h5py.File) -> bool:
    """Are the file's frames stored with one of the schema's codecs?"""
    return frames_codec(f) is not None


def _line(exc: BaseException) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def _copy(src: h5py.File, dst: h5py.File, frame=None) -> None:
    """Everything of ``src`` into ``dst``; growing datasets re-created with the writer's filters.
    ``frame(i)`` reads frame i (default: ``src``'s frames[i]; ``compact`` passes the verified
    reader's, which names a missing or damaged frame)."""
    frame = frame or (lambda i: src[S.FRAMES][i])
    dst.attrs.update(dict(src.attrs))

    def visit(name: str, obj) -> None:
        if isinstance(obj, h5py.Group):
            dst.require_group(name).attrs.update(dict(obj.attrs))
            return
        if name == S.FRAME_DIGEST:
            return  # bound to the stored chunks, which the copy stores anew: recomputed below
        if name == S.FRAMES:
            n, *shape = obj.shape
            d = dst.create_dataset(
                name,
                (n, *shape),
                maxshape=(None, *shape),
                dtype=obj.dtype,
                **chunked((1, *shape), codec=S.frame_codec(tuple(shape))),
            )
            for i in range(n):  # one frame at a time: a run does not fit in memory
                d[i] = frame(i)
        elif name in ROW_FIELDS and obj.ndim >= 1:
            d = dst.create_dataset(
                name,
                obj.shape,
                maxshape=(None, *obj.shape[1:]),
                dtype=obj.dtype,
                **chunked((ROW_FIELDS[name], *obj.shape[1:])),
            )
            if obj.shape[0]:
                d[...] = obj[()]
        else:
            src.copy(obj, dst, name=name)
            return
        d.attrs.update(dict(obj.attrs))

    src.visititems(visit)
    if S.FRAME_DIGEST in src:
        _redigest(dst)


def _redigest(dst: h5py.File) -> None:
    """The copy's frame digests, of its own stored chunks (acquisition/frame_identity.py)."""
    key = key_of(dst)
    n = dst[S.FRAMES].shape[0]
    rows = {fl.path: dst[fl.path][:n] for fl in S.PER_FRAME_FIELDS if fl.path in dst}
    digests = np.zeros((n, FRAME_DIGEST_BYTES), dtype=np.uint8)
    if key is not None:
        for i in range(n):
            chunk = stored_chunk(dst[S.FRAMES], i)
            digests[i] = frame_digest(key, i, chunk, row_bytes({k: v[i] for k, v in rows.items()}))
    dst.create_dataset(
        S.FRAME_DIGEST, data=digests, maxshape=(None, FRAME_DIGEST_BYTES), **chunked((ROW_BLOCK, FRAME_DIGEST_BYTES))
    )


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    return bool(np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"))


def _verify(src: h5py.File, copy: h5py.File) -> str:
    """'' when ``copy`` holds exactly ``src``'s data, else the first difference in words."""
    for key, value in src.attrs.items():
        if key not in copy.attrs or not _same(value, copy.attrs[key]):
            return f"attribute {key} differs"
    names: list[str] = []
    src.visit(names.append)
    names.sort(key=lambda name: name == S.FRAME_DIGEST)  # the digests last: a changed frame is named as such
    for name in names:
        a, b = src[name], copy.get(name)
        if isinstance(a, h5py.Group):
            continue
        if not isinstance(b, h5py.Dataset) or a.shape != b.shape or a.dtype != b.dtype:
            return f"{name}: missing or of another shape or type in the copy"
        if name == S.FRAMES:
            for i in range(a.shape[0]):
                if not np.array_equal(a[i], b[i]):
                    return f"{name}[{i}] differs"
        elif name == S.FRAME_DIGEST:  # of the copy's own chunks: checked against them instead
            rows = {fl.path: copy[fl.path][: a.shape[0]] for fl in S.PER_FRAME_FIELDS if fl.path in copy}
            bad = check_frames(copy, rows, a.shape[0]).findings()
            if bad:
                return bad[0]
            continue
        elif not _same(a[()], b[()]):
            return f"{name} differs"
        if dict(a.attrs).keys() != dict(b.attrs).keys() or not all(_same(a.attrs[k], b.attrs[k]) for k in a.attrs):
            return f"{name}: attributes differ"
    return ""


def compact(path: str | Path) -> Compacted:
    """Rewrite ``path`` with compressed, checksummed frames, verified before it replaces
    anything. RunLocked while a writer holds the run; RunFileError for a damaged or
    malformed file, or a copy that does not verify (the original is then untouched)."""
    path = Path(path)
    with SignalsAsExceptions():  # SIGTERM, SIGHUP: the copy removed and the lock released, as for Ctrl-C
        return _compact(path)


def _compact(path: Path) -> Compacted:
    lock = WriterLock.acquire(path)
    try:
        remove_stale_temps(path)
        before = path.stat().st_size if path.exists() else 0
        # the reader skips its length check while a writer holds the lock (it may be growing the
        # file): this process holds it now, and nobody else writes, so the check is made here
        problem = check_complete(path) if path.is_file() else ""
        if problem:
            raise RunFileError(f"{path}: {problem}; not compacted")
        with RunReader.open(path) as run:  # rows, attributes, images verified; frames as the copy reads them
            src = run.f
            n = run.n
            if frames_compressed(src):  # nothing to do: not read (dataset validate checks every frame)
                return Compacted(path, n, before, before, False)
            tmp = temp_path(path, ".compacting-")
            try:
                try:
                    with h5py.File(tmp, "w", libver="latest") as dst:
                        _copy(src, dst, run.frame)
                    fsync_path(tmp)
                    with h5py.File(tmp, "r") as copy:
                        problem = _verify(src, copy)
                except (OSError, RuntimeError, KeyError, ValueError) as exc:
                    raise RunFileError(f"{path}: compacting failed, the original is unchanged ({_line(exc)})") from None
                if problem:
                    raise RunFileError(
                        f"{path}: the compacted copy does not match ({problem}); the original is unchanged"
                    )
                os.replace(tmp, path)  # atomic: readers see the old file or the new one, never a mix
            finally:
                tmp.unlink(missing_ok=True)
        return Compacted(path, n, before, path.stat().st_size, True)
    finally:
        lock.release()
