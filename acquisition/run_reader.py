"""The one read path for run files: opened, checked against the schema and verified as it is read.

``RunReader.open(path)`` refuses, in one line naming the file, the dataset and the frame, any file
that ``dataset validate`` would refuse for its form or content (acquisition/run_checks.py):

* the file itself: missing, not a regular file (a named pipe would block for ever), cut short (its
  superblock records its length), not HDF5, a codec this installation cannot decode
  (``open_for_reading``, within a second);
* the schema: every dataset and root attribute of the table with its dtype and shape, a known
  sensor kind, the root attributes against their checksum (acquisition/attr_checksum.py; a file
  written before it: a note), checksums on every growing dataset (or on none: a file written before
  them), a status of the schema's, text that is UTF-8;
* the rows, read in full (their chunks' checksums checked by HDF5): one per frame (exactly one once
  the run is closed), finite numbers, time increasing, the capture grid contiguous from 0, phases
  within the file's own list, levels not negative; the full-rate stream finite and never going
  back in time; the object image and the reference frame readable.

* the frames, every one, when the file is opened, without decoding them (acquisition/frame_checks.py):
  each chunk present, as written (its Fletcher-32 checksum) and in its place (its identity digest,
  bound to its index, its row and the run: acquisition/frame_identity.py), so a zeroed page, a
  swapped or a foreign chunk is refused by every reader; a run still being written serves the frames
  committed so far. The full-rate stream's rows against their digests too.

A process that opens the same closed, settled run file again (its device, inode, size and change
times as when its frames were found sound, none of them within ``SETTLED_S`` of that check) does not
read every chunk again: a command that opens a split's runs once per part and per baseline pays for
one pass. Any write to the file changes its times (``SETTLED_S`` keeps a write within the file
system's timestamp granularity from going unseen); a fresh process checks in full.

Frames are also checked as they are read (``frame``: HDF5 checks the chunk's checksum). What the
reader leaves to ``dataset validate`` are its judgements: black, constant or saturated frames,
wrench–frame skew beyond a threshold, and whether a run completed (``split`` asks that itself).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import h5py
import numpy as np

from acquisition import attr_checksum
from acquisition import schema as S
from acquisition.chunk_checksum import ChunkIndexError
from acquisition.frame_checks import check_frames, stream_findings
from acquisition.hdf5_open import check_complete, open_swmr_read
from acquisition.run_checks import (
    checksum_findings,
    first_line,
    image_findings,
    metadata_problem,
    read_rows,
    read_stream,
    row_count_findings,
    row_findings,
    status_findings,
)
from acquisition.run_layout import attr_problems, decode_phases, field_problems, frame_filter_problems
from acquisition.writer_lock import RunFileError, live_writer

__all__ = ["RunReader", "open_for_reading"]

SETTLED_S = 2.0  # a file last changed this long before its frames were checked keeps that verdict
_SOUND: dict[tuple[int, ...], int] = {}  # a closed run file's identity → the frame count found sound
_SOUND_MAX = 256
now_ns = time.time_ns  # the wall clock the file system's times are compared with (tests set it)


def _identity(f: h5py.File) -> tuple[int, ...] | None:
    """(device, inode, size, mtime, ctime) of the file ``f`` has open, from its own descriptor (a file
    renamed over the path meanwhile is not the one asked about); None when the descriptor cannot be
    had (another HDF5 driver) or the file is not settled."""
    try:
        st = os.fstat(f.id.get_vfd_handle())
    except (OSError, ValueError, TypeError, RuntimeError):
        return None
    if now_ns() - max(st.st_mtime_ns, st.st_ctime_ns) < SETTLED_S * 1e9:
        return None  # changed too recently: a write in the same timestamp tick would go unseen
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns


def open_for_reading(path: str | Path) -> h5py.File:
    """A run file for reading, also while it is being written or after its writer crashed: the file
    checks only (present, complete, HDF5, codecs decodable). ``RunReader.open`` checks the rest.

    Fails within a second, naming the file, when the file is cut short or damaged.
    """
    path = Path(path)
    if not path.exists():
        raise RunFileError(f"{path}: no such file")
    if path.is_dir():
        raise RunFileError(f"{path}: is a folder, expected a run file (.h5)")
    if not path.is_file():  # a named pipe would block the first read for ever, a device read without end
        raise RunFileError(f"{path}: not a regular file (a named pipe, device or socket), expected a run file (.h5)")
    try:
        problem = check_complete(path)
    except OSError as exc:
        raise RunFileError(f"{path}: cannot be read ({exc.strerror})") from None
    # A live writer may be between growing the file and writing its new end.
    if problem and not (problem.startswith("truncated:") and live_writer(path)):
        raise RunFileError(f"{path}: {problem}")
    try:
        f = open_swmr_read(path)
    except (OSError, RuntimeError, KeyError) as exc:
        raise RunFileError(f"{path}: not a readable HDF5 run file ({first_line(exc)})") from None
    undecodable = frame_filter_problems(f)
    if undecodable:
        f.close()
        raise RunFileError(f"{path}: {S.FRAMES}: {undecodable[0]}")
    return f


def refusal(path: Path, problems: list[str]) -> RunFileError:
    """One line for a file with ``problems``: the first, and how many more validate lists."""
    more = f" (and {len(problems) - 1} more problem(s): dataset validate lists them)" if len(problems) > 1 else ""
    return RunFileError(f"{path}: {problems[0]}{more}")


class RunReader:
    """A verified run file (see the module docstring). ``rows`` holds every per-frame field's first
    ``n`` rows (an optional field the file lacks: its fill value), read and checked at open."""

    def __init__(self, path: Path, f: h5py.File):
        self.path = path
        self.f = f
        self.n = 0
        self.rows: dict[str, np.ndarray] = {}
        self.images: dict[str, np.ndarray] = {}
        self.status = self.reason = ""
        self.notes: list[str] = []
        self._stream: np.ndarray | None = None
        self._frames_verified = False

    # -- opening ------------------------------------------------------------------------
    @classmethod
    def open(cls, path: str | Path) -> "RunReader":
        """The run at ``path``, verified (module docstring); RunFileError, one line, when it is not sound."""
        path = Path(path)
        f = open_for_reading(path)
        reader = cls(path, f)
        try:
            problems = reader._verify()
        except (OSError, RuntimeError, KeyError, ValueError) as exc:  # damage beyond what the checks expect
            problems = [f"unreadable ({first_line(exc)})"]
        if problems:
            f.close()
            raise refusal(path, problems)
        return reader

    def _verify(self) -> list[str]:
        f = self.f
        damaged = metadata_problem(f)
        if damaged:
            return [damaged]
        fields = field_problems(f)
        missing = [name for name, p in fields.items() if p == "missing"]
        if missing:
            return [f"not a run file: missing {', '.join(missing)}"]
        problems = [f"malformed run file: {name}: {p}" for name, p in fields.items()]
        problems += [f"malformed run file: attribute {name}: {p}" for name, p in attr_problems(f).items()]
        if problems:
            return problems
        damaged, note = attr_checksum.problem(f)
        if damaged:
            return [damaged]
        sound = {fl.path for fl in S.FIELDS if fl.path in f}
        problems, self.notes = checksum_findings(f, sound)
        self.notes += [note] if note else []
        self.status, self.reason, found = status_findings(f, sound)
        problems += found
        self.n = f[S.FRAMES].shape[0]
        problems += row_count_findings(f, sound, self.n, self.status)
        present = [fl.path for fl in S.PER_FRAME_FIELDS if fl.path in sound]
        if problems:
            return problems
        self.rows, problems = read_rows(f, present, self.n)
        for fl in S.PER_FRAME_FIELDS:
            if fl.path not in self.rows and not problems:  # an older file: the table's fill value
                self.rows[fl.path] = np.full((self.n, *fl.shape), fl.fill, dtype=fl.dtype)
        problems += row_findings(self.rows, self.n, len(self.phases))
        if S.WRENCH_STREAM in sound:
            self._stream, found = read_stream(f, S.WRENCH_STREAM)
            problems += found or stream_findings(f, self._stream)
        self.images, found = image_findings(f, sound)
        problems += found
        if not problems:
            problems += self._verify_frames()
        return problems

    def _verify_frames(self) -> list[str]:
        """Every frame chunk present, as written and in its place (acquisition/frame_checks.py), read once
        when the run is opened. A run still being written (or whose writer crashed) may end in frames
        not yet committed: those are left out, with a note; damage before them is refused."""
        before = _identity(self.f) if self.status != "running" else None
        if before is not None and _SOUND.get(before) == self.n:  # found sound before, unchanged since
            self._frames_verified = True
            return []
        try:
            check = check_frames(self.f, self.rows, self.n)
        except ChunkIndexError as exc:  # no frame can be located: one line for the dataset
            return [f"{S.FRAMES}: {exc}; the file is damaged"]
        self._frames_verified = True
        if not check.bad:
            if before is not None and _identity(self.f) == before:
                if len(_SOUND) >= _SOUND_MAX:
                    _SOUND.clear()
                _SOUND[before] = self.n
            return []
        tail = check.tail_from(self.n)
        if self.status == "running" and min(check.bad) >= tail:
            self.notes.append(
                f"frames {tail}..{self.n - 1} not committed yet (being written, or its writer stopped): left out; "
                "`rig run-protocol --resume` keeps the frames that reached the disk"
            )
            self.n = tail
            self.rows = {name: values[:tail] for name, values in self.rows.items()}
            return []
        why = (
            "the run is still running or its writer crashed: `rig run-protocol --resume` keeps the frames that "
            "reached the disk"
            if self.status == "running"
            else "the file is damaged"
        )
        findings = check.findings()
        return [f"{findings[0]}; {why}", *findings[1:]]

    # -- what it holds ------------------------------------------------------------------
    @property
    def attrs(self) -> h5py.AttributeManager:
        return self.f.attrs

    def text(self, name: str, default: str = "") -> str:
        """A root attribute as text (an optional one the file lacks: ``default``)."""
        value = self.f.attrs.get(name)
        if value is None:
            return default
        return value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)

    def number(self, name: str) -> float:
        return float(self.f.attrs[name])

    @property
    def phases(self) -> tuple[str, ...]:
        return decode_phases(self.f)

    @property
    def frame_shape(self) -> tuple[int, int, int]:
        h, w, c = self.f[S.FRAMES].shape[1:]
        return int(h), int(w), int(c)

    @property
    def sensor_profile(self) -> str:
        """The recorded sensor profile (``SensorProfile.record()`` text), "" when the run has none."""
        return self.text(S.ATTR_SENSOR_PROFILE).strip()

    @property
    def stream(self) -> np.ndarray | None:
        """The full-rate wrench stream (verified at open); None when the file has none."""
        return self._stream

    def image(self, name: str) -> np.ndarray:
        """The object image or the reference frame (read and checked at open)."""
        return self.images[name]

    def frame(self, i: int) -> np.ndarray:
        """Frame ``i``; RunFileError naming the file and the frame when its chunk is missing or damaged."""
        if not 0 <= i < self.n:
            raise RunFileError(f"{self.path}: {S.FRAMES}[{i}]: no such frame (the run has {self.n})")
        d = self.f[S.FRAMES]
        try:
            if d.chunks is not None and d.id.get_chunk_info_by_coord((i, 0, 0, 0)).byte_offset is None:
                raise RunFileError(f"{self.path}: {S.FRAMES}[{i}]: never written (no chunk on disk)")
            return d[i]
        except (OSError, RuntimeError, ValueError) as exc:
            raise RunFileError(
                f"{self.path}: {S.FRAMES}[{i}]: checksum mismatch or missing bytes ({first_line(exc)}); "
                "the file is damaged"
            ) from None

    def frame_problems(self, upto: int | None = None) -> list[str]:
        """Every frame chunk of frames 0..upto-1 (default: all) checked again without decoding it:
        present, its checksum, its identity digest; the problems, one line per kind (empty when sound)."""
        upto = self.n if upto is None else upto
        try:
            return check_frames(self.f, {k: v[:upto] for k, v in self.rows.items()}, upto).findings()
        except ChunkIndexError as exc:  # no frame can be located: one line for the dataset
            return [f"{S.FRAMES}: {exc}"]

    def verify_frames(self) -> None:
        """Every frame verified (``frame_problems``), as a RunFileError naming the first damaged frame;
        nothing to do when ``open`` verified them (it does, unless the file was too damaged to try)."""
        if self._frames_verified:
            return
        problems = self.frame_problems()
        if problems:
            why = (
                "the run is still running or its writer crashed: `rig run-protocol --resume` keeps the frames "
                "that reached the disk"
                if self.status == "running" and problems[0].startswith(f"{S.FRAMES}[")
                else "the file is damaged"
            )
            raise refusal(self.path, [f"{problems[0]}; {why}", *problems[1:]])

    # -- closing ------------------------------------------------------------------------
    def close(self) -> None:
        self.f.close()

    def __enter__(self) -> "RunReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
