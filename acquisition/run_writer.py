"""Writing run files: append-only, crash-safe, never claiming more than is on disk.

* Written in SWMR mode and flushed after every frame, so ``dataset info`` can read a
  run while it grows and a ``kill -9`` loses at most the frame being written.
* A frame counts only once its row and its frame are flushed; a write that fails
  (disk full) is rolled back to the last counted frame, recorded as the reason, and
  raised as RunFileError, so no partial or all-zero frame is ever committed.
* Frames, rows and the two images carry Fletcher-32 checksums per chunk: corruption fails
  on read. Frames are losslessly compressed (``schema.FRAME_CODECS``), one frame per chunk.
* Every dataset comes from the schema's field table: a field added there is written.
* Created under a temporary name and renamed into place once the header, reference
  frame and object image are on disk: a crash leaves nothing at ``--out``.
* One writer at a time: ``writer_lock.WriterLock`` (a second run, ``--resume``).
* The header says which sensor profile the frames came from, or that none is known
  (``sensor_profile`` "": a real sensor's run or an import without ``--profile``).

Reopening a run to append (``--resume``) is acquisition/run_resume.py; reading one is
acquisition/run_reader.py. docs/run-file.md has the details.
"""
# Over 400 lines (419): RunWriter is one class: create, append with rollback, the space and tamper
# checks and close share the open file's state; its header is apart (run_header.py), reopening in run_resume.py.

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np

from acquisition import schema as S
from acquisition.frame_identity import frame_digest, key_of, row_bytes, stored_chunk, stream_digests
from acquisition.run_checks import first_line as _first_line
from acquisition.run_header import RunHeader, write_header
from acquisition.run_layout import decode_phases
from acquisition.run_storage import ROW_BLOCK, fsync_path, remove_stale_temps, temp_path
from acquisition.write_failure import SPACE_MARGIN_BYTES, describe_failure, space_shortfall
from acquisition.writer_lock import RunFileError, WriterLock
from common.sensors import SENSOR_KINDS

log = logging.getLogger("acquisition")


# (name, shape per frame, dtype, units), from the schema's field table
PER_FRAME = tuple((f.path, f.shape, f.dtype, f.units) for f in S.PER_FRAME_FIELDS)


class RunWriter:
    def __init__(self, f: h5py.File, path: Path, lock: WriterLock):
        self.f = f
        self.path = path
        self.lock = lock
        self.n = f[S.FRAMES].shape[0]
        self._frames = f[S.FRAMES]
        self._frame_shape = self._frames.shape[1:]
        self._frame_dtype = self._frames.dtype
        self._frame_memory = h5py.h5s.create_simple((1, *self._frame_shape))  # one frame, as written
        # the fields this file has: an older file lacks the optional ones added since
        self._rows = {fl.path: f[fl.path] for fl in S.PER_FRAME_FIELDS if fl.path in f}
        self._stream = f.get(S.WRENCH_STREAM)
        self._stream_n = self._stream.shape[0] if self._stream is not None else 0  # rows counted
        # frame identity (acquisition/frame_identity.py): a file written before it has no digests to extend
        self._key = key_of(f)
        self._digests = f.get(S.FRAME_DIGEST) if self._key else None
        self._stream_digests = f.get(S.STREAM_DIGEST) if self._key and self._stream is not None else None
        self._rows_len = min(d.shape[0] for d in self._grown_with_rows())
        self.phases = decode_phases(f)
        self._row_spaces: dict[str, tuple] = {}  # per row dataset: (memory space, file space) of one row
        self._stream_layout: tuple[tuple[int, ...], np.dtype] | None = None  # the stream's row shape and dtype
        self._failure = ""  # set when a write failed: the file is closed with it as its reason
        self._tampered = False  # changed by another process: closed without reading it again
        self.retake = 0  # a resume that re-does a level: its number (superseded/retake-N), else 0
        # what the file is on disk, so that a change by another process is noticed (``_check_file``)
        st = os.stat(path)
        self._file_id = (st.st_dev, st.st_ino)
        self._size = st.st_size

    @classmethod
    def claim(cls, path: str | Path) -> WriterLock:
        """The writer lock of a new run at ``path``, taken before anything moves; pass it to
        ``create``. RunLocked names another live writer; RunFileError if ``path`` exists."""
        path = Path(path)
        lock = WriterLock.acquire(path)
        if path.exists():
            lock.release()
            raise RunFileError(f"{path}: exists; choose another --out, or --resume it")
        return lock

    @classmethod
    def create(
        cls,
        path: str | Path,
        header: RunHeader,
        frame_shape: tuple[int, int, int],
        object_image: np.ndarray,
        reference_frame: np.ndarray,
        *,
        lock: WriterLock | None = None,
        compress: bool = True,
        codec: str | None = None,
    ) -> "RunWriter":
        """A new run file at ``path``, which must not exist. Takes the writer lock (or uses
        ``lock``, already taken); RunLocked names another live writer, RunFileError the rest.
        ``codec``: the frames' codec (a name in the schema's FRAME_CODECS; None: the image
        codec where the frames suit it, see ``schema.frame_codec``). ``compress=False``
        writes frames uncompressed, as files before compression were."""
        path = Path(path)
        if header.sensor_kind not in SENSOR_KINDS:  # before anything is taken or written
            kinds = ", ".join(SENSOR_KINDS)
            raise RunFileError(f"{path}: sensor kind {header.sensor_kind!r} is not one of {kinds} (common/sensors.py)")
        lock = lock or WriterLock.acquire(path)
        try:
            if path.exists():
                raise RunFileError(f"{path}: exists; choose another --out, or --resume it")
            remove_stale_temps(path)
            tmp = temp_path(path, ".creating-")
            try:
                with h5py.File(tmp, "w", libver="latest") as f:
                    chosen = S.frame_codec(tuple(frame_shape), codec) if compress else None
                    write_header(f, header, frame_shape, object_image, reference_frame, chosen)
                fsync_path(tmp)
                os.replace(tmp, path)  # only a complete header ever appears at the run's name
            except (OSError, RuntimeError) as exc:
                raise RunFileError(f"{path}: cannot create the run file ({_first_line(exc)})") from None
            finally:
                tmp.unlink(missing_ok=True)
            f = h5py.File(path, "r+", libver="latest")
            f.swmr_mode = True
            return cls(f, path, lock)
        except BaseException:
            lock.release()
            raise

    @classmethod
    def reopen(cls, path: str | Path, supersede=None) -> "RunWriter":
        """Open a run to append to it (``--resume``), every committed chunk verified first:
        acquisition/run_resume.py. RunLocked while another process writes it, RunFileError naming
        the file, the dataset and the frame when it is damaged or not a well-formed run file.
        ``supersede``: which committed frames a resume re-takes (run_resume.reopen)."""
        from acquisition.run_resume import reopen

        return reopen(path, cls, supersede)

    def _truncate_to(self, n: int) -> None:
        """Every growing dataset shrunk to the counted frames (and stream rows), flushed."""
        self._row_spaces = {}
        for d in [self._frames, *self._grown_with_rows()]:
            if d.shape[0] != n:
                d.resize(n, axis=0)
        for d in (self._stream, self._stream_digests):
            if d is not None and d.shape[0] != self._stream_n:
                d.resize(self._stream_n, axis=0)
        self._rows_len = n
        self.f.flush()

    def _grown_with_rows(self) -> list[h5py.Dataset]:
        """The datasets that grow a row block at a time: the per-frame rows and the frame digests."""
        return [*self._rows.values(), *([self._digests] if self._digests is not None else [])]

    @property
    def capture_indices(self) -> np.ndarray:
        return self._rows[S.CAPTURE_INDEX][: self.n]

    @property
    def last_t_frame_s(self) -> float | None:
        """The newest frame's t_frame_s: the next one must be later (see docs/run-file.md)."""
        return float(self._rows[S.T_FRAME][self.n - 1]) if self.n else None

    @property
    def last_stream_t_s(self) -> float | None:
        """The newest full-rate wrench sample's time (rig clock, with the resume offset), if any."""
        return float(self._stream[self._stream_n - 1, 0]) if self._stream is not None and self._stream_n else None

    @property
    def records_stream(self) -> bool:
        return self._stream is not None  # files written before the full-rate wrench have no place for it

    def phase_index(self, phase: str) -> int:
        """``phase``'s index in this file's own ``phases`` attribute (a resumed file keeps its order)."""
        try:
            return self.phases.index(phase)
        except ValueError:
            raise RunFileError(
                f"{self.path}: phase {phase!r} is not in the file's phases ({', '.join(self.phases)})"
            ) from None

    def header_attr(self, name: str):
        return self.f.attrs[name]

    def append(self, frame: np.ndarray, stream: np.ndarray | None = None, **row) -> None:
        """One capture: the frame, its row (keys: the per-frame dataset names of the schema's
        table) and optionally the full-rate wrench samples since the last capture
        (``stream``: (M, 7) rows of t_s and the wrench, time not going back).

        Counted only after all are flushed. RunFileError when the disk is full or a write
        fails: nothing of this frame stays in the file, and every earlier frame does.
        """
        if self._failure:
            raise RunFileError(f"{self.path}: {self._failure}")
        i = self.n
        self._check_file(i)  # before HDF5 reads anything: in a file cut short its reads retry without end
        frames = self._frames
        if frame.shape != self._frame_shape:
            raise RunFileError(f"{self.path}: frame shape {frame.shape} differs from the run's {self._frame_shape}")
        if frame.dtype != self._frame_dtype:  # no silent conversion (a 16-bit or float image would wrap or clip)
            raise RunFileError(f"{self.path}: frame dtype {frame.dtype}, the run's frames are {self._frame_dtype}")
        self._check_row(i, row)
        self._check_space(i, frame.nbytes)
        try:
            # Stream and rows first (row datasets grow a block at a time), the frame last:
            # the frame count is the number of valid rows, so a crash in between leaves a
            # row without a frame (trimmed on resume), never a frame without its row.
            if stream is not None and len(stream) and self._stream is not None:
                self._write_stream(np.asarray(stream))
            if self._rows_len <= i:
                for d in self._grown_with_rows():
                    d.resize(i + ROW_BLOCK, axis=0)
                self._rows_len = i + ROW_BLOCK
                self._row_spaces = {}  # the datasets grew: their file spaces are new
            for name, d in self._rows.items():
                self._write_row(name, d, i, row[name])
            self._write_frame(frames, i, frame)
            if self._digests is not None:  # bound to this index and run: after the frame, whose stored chunk it hashes
                assert self._key is not None
                digest = frame_digest(self._key, i, stored_chunk(frames, i), row_bytes(row))
                self._write_row(S.FRAME_DIGEST, self._digests, i, digest)
            self.f.flush()
        except (OSError, RuntimeError) as exc:  # h5py reports a failed flush as RuntimeError
            raise self._fail(i, exc) from None
        self._check_file(i)
        self.n = i + 1
        if stream is not None and len(stream) and self._stream is not None:
            self._stream_n += len(stream)

    def _write_frame(self, frames: h5py.Dataset, i: int, frame: np.ndarray) -> None:
        """``frames.resize(i + 1, axis=0); frames[i] = frame`` through h5py's low-level calls:
        the same bytes in the same chunk (``append`` has checked the frame's shape and dtype)."""
        _append_rows(frames, i, np.ascontiguousarray(frame).reshape(1, *self._frame_shape), self._frame_memory)

    def _write_stream(self, stream: np.ndarray) -> None:
        """``self._stream[m:] = stream`` after growing it by ``len(stream)`` rows, through
        h5py's low-level calls: the same bytes in the same chunks."""
        d = self._stream
        assert d is not None
        if self._stream_layout is None:  # h5py's Dataset.shape and .dtype ask HDF5 each time
            self._stream_layout = (d.shape[1:], d.dtype)
        width, dtype = self._stream_layout
        m = self._stream_n
        data = np.ascontiguousarray(stream, dtype=dtype)
        if data.shape[1:] != width:
            raise ValueError(f"{self.path}: {S.WRENCH_STREAM}: rows of shape {data.shape[1:]}, the field's are {width}")
        if self._stream_digests is not None:  # first: a crash then leaves digests without rows, never the reverse
            assert self._key is not None
            digests = stream_digests(self._key, m, data)
            _append_rows(self._stream_digests, m, digests, h5py.h5s.create_simple(digests.shape))
        _append_rows(d, m, data, h5py.h5s.create_simple(data.shape))

    def _write_row(self, name: str, d: h5py.Dataset, i: int, value) -> None:
        """``d[i] = value`` through h5py's low-level write: the same bytes in the same
        chunk, without the high-level indexing (ten fields a frame, most of the writer's
        Python time). The value is converted to the field's dtype as ``d[i] =`` would,
        a wrong shape refused as it would be."""
        cached = self._row_spaces.get(name)
        if cached is None:  # h5py's Dataset.shape and .dtype ask HDF5 each time: once per block
            shape = d.shape[1:]
            cached = (h5py.h5s.create_simple((1, *shape)), d.id.get_space(), d.dtype, shape, (0,) * len(shape))
            self._row_spaces[name] = cached
        memory, file, dtype, shape, zeros = cached
        data = np.asarray(value, dtype=dtype)
        if data.shape != shape:
            raise ValueError(f"{self.path}: {name}: value of shape {data.shape}, the field is {shape}")
        file.select_hyperslab((i, *zeros), (1, *shape))
        d.id.write(memory, file, np.ascontiguousarray(data).reshape(1, *shape))

    def _check_row(self, i: int, row: Mapping) -> None:
        """Every field of this file in ``row``, nothing outside the schema's table (a typo
        would otherwise be dropped silently)."""
        table = {f.path for f in S.PER_FRAME_FIELDS}
        unknown = [name for name in row if name not in table]
        if unknown:
            raise RunFileError(
                f"{self.path}: frame {i}: {', '.join(unknown)} not in the run-file field table (acquisition/schema.py)"
            )
        missing = [name for name in self._rows if name not in row]
        if missing:
            raise RunFileError(f"{self.path}: frame {i} has no {', '.join(missing)}")

    def _check_space(self, i: int, frame_bytes: int) -> None:
        """Stop before a write that cannot fit (acquisition/write_failure.py says why it matters)."""
        short = space_shortfall(self.path, frame_bytes + SPACE_MARGIN_BYTES)
        if short is not None:
            raise self._fail(i, short)

    def _fail(self, i: int, exc: BaseException) -> RunFileError:
        """Roll the file back to its ``i`` counted frames and record why; the error to raise.

        HDF5 keeps a frame that failed to reach the disk in its chunk cache and retries it
        at every flush, and at interpreter exit, where the retry crashed the process
        (rc 139): shrinking the datasets to the counted frames discards it.
        """
        what, self._failure = describe_failure(exc, i)
        try:
            self._truncate_to(i)
            self.f[S.STATUS][()] = np.bytes_("aborted")
            self.f[S.STATUS_REASON][()] = np.bytes_(self._failure.encode("utf-8")[: S.REASON_LEN])
            self.f.flush()
        except (OSError, RuntimeError) as again:
            log.error("%s: after %s, rolling back also failed: %s", self.path, what, _first_line(again))
        return RunFileError(f"{self.path}: {self._failure}")

    def _check_file(self, i: int) -> None:
        """After a commit: the file at our path is still ours and no shorter than what HDF5 has
        written. Another process that replaced or cut it (a sync tool, a careless `cp`, a full quota
        enforced by truncation) would otherwise go unseen until a reader failed on it."""
        try:
            st = os.stat(self.path)
            written = self.f.id.get_filesize()
        except (OSError, RuntimeError) as exc:
            raise self._changed(i, f"it can no longer be examined ({_first_line(exc)})") from None
        if (st.st_dev, st.st_ino) != self._file_id:
            raise self._changed(i, "another file has taken its name (it was replaced or moved)")
        if st.st_size < min(written, self._size):
            raise self._changed(i, f"it was cut from {self._size} to {st.st_size} bytes by another process")
        self._size = max(st.st_size, written)

    def _changed(self, i: int, what: str) -> RunFileError:
        """The file changed under this writer: no more frames go into it; the reason says what changed
        and how many frames were committed before it (readers name the damaged ones)."""
        self._failure = (
            f"the file changed while it was written: {what}; {i} frame(s) were committed before this was "
            "noticed (`dataset validate` names any damaged)"
        )
        self._tampered = True  # from now on only written to (the status), never read: see ``close``
        try:
            self.f[S.STATUS][()] = np.bytes_("aborted")
            self.f[S.STATUS_REASON][()] = np.bytes_(self._failure.encode("utf-8")[: S.REASON_LEN])
            self.f.flush()
        except (OSError, RuntimeError) as exc:
            log.error("%s: recording that the file changed also failed: %s", self.path, _first_line(exc))
        return RunFileError(f"{self.path}: {self._failure}")

    def verify_written(self) -> None:
        """Before a run is reported complete: the file read back as it is on disk — every frame chunk
        present, as written and in its place (checksum and identity digest), every row chunk, the
        stream against its digests — so that a file changed under its writer is never called complete.
        Only that the file holds what was written: what was written (a NaN in a row, say) is for the
        readers to judge. RunFileError, the file marked aborted, when it is not what was written."""
        from acquisition.frame_checks import check_frames, stream_findings
        from acquisition.run_checks import read_rows
        from acquisition.run_reader import open_for_reading

        self._check_file(self.n)
        try:
            self._truncate_to(self.n)  # the row blocks trimmed to the frames, as at close
            with open_for_reading(self.path) as f:
                if f[S.FRAMES].shape[0] != self.n:
                    raise RunFileError(
                        f"{self.path}: it holds {f[S.FRAMES].shape[0]} frames where {self.n} were written"
                    )
                rows, problems = read_rows(f, list(self._rows), self.n)
                if not problems:
                    problems = check_frames(f, rows, self.n).findings()
                if not problems and self._stream is not None:
                    problems = stream_findings(f, f[S.WRENCH_STREAM][: self._stream_n])
            if problems:
                raise RunFileError(f"{self.path}: {problems[0]}")
        except RunFileError as exc:
            problem = str(exc).removeprefix(f"{self.path}: ")
            raise self._changed(self.n, f"read back, {problem}") from None
        except (OSError, RuntimeError, KeyError, ValueError) as exc:
            raise self._changed(self.n, f"read back, {_first_line(exc)}") from None

    def set_status(self, status: str, reason: str = "") -> None:
        """Record how the run ended. After a failed write the failure stays the reason. "complete" only
        for a file read back as written (``verify_written``)."""
        if status == "complete" and not self._failure:
            self.verify_written()
        if self._failure:
            status = "aborted"
            reason = self._failure if not reason or reason in self._failure else f"{self._failure}; {reason}"
        try:
            self.f[S.STATUS][()] = np.bytes_(status[: S.STATUS_LEN])
            self.f[S.STATUS_REASON][()] = np.bytes_(reason.encode("utf-8")[: S.REASON_LEN])
            self.f.flush()
        except (OSError, RuntimeError) as exc:
            raise RunFileError(f"{self.path}: cannot record status {status!r} ({_first_line(exc)})") from None

    def set_sim_solver_warnings(self, count: int) -> None:
        """A simulated run: how many contact solves stopped short of their tolerance (0: none)."""
        if S.SIM_SOLVER_WARNINGS in self.f:  # files created before the field have no place for it
            self.f[S.SIM_SOLVER_WARNINGS][()] = np.int64(count)
            self.f.flush()

    def close(self) -> None:
        """Trim to the counted frames, close, release the lock; RunFileError if closing failed."""
        try:
            if self.f.id.valid:
                try:
                    if not self._tampered:  # trimming reads the file's index, which another process may have cut
                        self._truncate_to(self.n)
                    self.f.close()
                except (OSError, RuntimeError) as exc:
                    raise RunFileError(
                        f"{self.path}: closing failed ({_first_line(exc)}); its {self.n} flushed frames are kept"
                    ) from None
        finally:
            self.lock.release()


def _append_rows(d: h5py.Dataset, at: int, data: np.ndarray, memory) -> None:
    """``d.resize(at + len(data), axis=0); d[at:] = data`` through h5py's low-level calls
    (``data`` C-contiguous in ``d``'s dtype, ``memory`` its dataspace): the same bytes in
    the same chunks, without the high-level indexing."""
    d.id.set_extent((at + len(data), *data.shape[1:]))
    file = d.id.get_space()
    file.select_hyperslab((at, *(0,) * (data.ndim - 1)), data.shape)
    d.id.write(memory, file, data)
