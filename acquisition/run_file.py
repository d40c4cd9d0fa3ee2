"""Append-only, crash-safe HDF5 run files.

Written in SWMR mode and flushed after every frame, so ``dataset info`` can read a
run while it grows and a ``kill -9`` loses at most the frame being written. After a
crash the file keeps HDF5's "open for writing" flag: readers open it with
``swmr=True`` (``open_for_reading`` does), and ``recover`` copies it into a clean
file so that ``--resume`` can append again.
"""

from __future__ import annotations

import datetime as dt
import os
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from acquisition import schema as S
from rig import __version__
from rig.errors import RigError


class RunFileError(RigError):
    """A run file is missing, not HDF5, or not what was expected; names the file."""


@dataclass(frozen=True)
class RunHeader:
    protocol_name: str
    protocol_toml: str
    rig_config: str
    object_name: str
    object_geometry: str
    sensor_kind: str
    mm_per_px: float
    capture_hz: float
    frames_planned: int
    contact_origin: tuple[float, float, float, float]
    phases: tuple[str, ...]


PER_FRAME = (
    (S.WRENCH, (6,), "f8", "N, N, N, N·mm, N·mm, N·mm"),
    (S.POSE_COMMANDED, (4,), "f8", "mm, mm, mm, deg"),
    (S.POSE_MEASURED, (4,), "f8", "mm, mm, mm, deg"),
    (S.T_FRAME, (), "f8", "s (rig clock)"),
    (S.T_CAPTURE, (), "f8", "s (protocol time)"),
    (S.WRENCH_SKEW, (), "f8", "s"),
    (S.CAPTURE_INDEX, (), "i8", ""),
    (S.STEP_INDEX, (), "i4", ""),
    (S.PHASE_INDEX, (), "i1", ""),
    (S.LEVEL, (), "i1", ""),
)


ROW_BLOCK = 256  # per-row datasets grow in blocks; the frame count says how many rows are valid


class RunWriter:
    def __init__(self, f: h5py.File, path: Path):
        self.f = f
        self.path = path
        self.n = f[S.FRAMES].shape[0]
        self._frames = f[S.FRAMES]
        self._rows = {name: f[name] for name, *_ in PER_FRAME}
        self._rows_len = min(d.shape[0] for d in self._rows.values())

    @classmethod
    def create(cls, path: str | Path, header: RunHeader, frame_shape: tuple[int, int, int],
               object_image: np.ndarray, reference_frame: np.ndarray) -> "RunWriter":
        path = Path(path)
        if path.exists():
            raise RunFileError(f"{path}: exists; choose another --out, or --resume it")
        f = h5py.File(path, "w", libver="latest")
        try:
            a = f.attrs
            a[S.ATTR_SCHEMA] = S.SCHEMA_VERSION
            a[S.ATTR_SOFTWARE] = __version__
            a[S.ATTR_CREATED] = dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")
            a[S.ATTR_PROTOCOL_NAME] = header.protocol_name
            a[S.ATTR_PROTOCOL] = header.protocol_toml
            a[S.ATTR_RIG_CONFIG] = header.rig_config
            a[S.ATTR_OBJECT] = header.object_name
            a[S.ATTR_OBJECT_GEOMETRY] = header.object_geometry
            a[S.ATTR_SENSOR_KIND] = header.sensor_kind
            a[S.ATTR_MM_PER_PX] = header.mm_per_px
            a[S.ATTR_CAPTURE_HZ] = header.capture_hz
            a[S.ATTR_FRAMES_PLANNED] = header.frames_planned
            a[S.ATTR_CONTACT_ORIGIN] = np.asarray(header.contact_origin, dtype=float)
            a[S.ATTR_PHASES] = list(header.phases)
            h, w, c = frame_shape
            frames = f.create_dataset(S.FRAMES, (0, h, w, c), maxshape=(None, h, w, c), chunks=(1, h, w, c),
                                      dtype="u1")
            frames.attrs["units"] = "BGR, 0-255"
            for name, shape, dtype, units in PER_FRAME:
                d = f.create_dataset(name, (0, *shape), maxshape=(None, *shape), chunks=(256, *shape), dtype=dtype)
                d.attrs["units"] = units
            f.create_dataset(S.OBJECT_IMAGE, data=object_image.astype(np.uint8))
            f.create_dataset(S.REFERENCE_FRAME, data=reference_frame.astype(np.uint8))
            f.create_dataset(S.STATUS, data=np.bytes_("running"), dtype=f"S{S.STATUS_LEN}")
            f.create_dataset(S.STATUS_REASON, data=np.bytes_(""), dtype=f"S{S.REASON_LEN}")
            f.swmr_mode = True
            f.flush()
        except BaseException:
            f.close()
            raise
        return cls(f, path)

    @classmethod
    def reopen(cls, path: str | Path) -> "RunWriter":
        """Open a run to append to it, recovering it first if its writer crashed."""
        path = Path(path)
        if not path.exists():
            raise RunFileError(f"{path}: no such run file to resume")
        try:
            f = h5py.File(path, "r+", libver="latest")
        except OSError as exc:
            if "consistency flag" not in str(exc) and "already open for write" not in str(exc):
                raise RunFileError(f"{path}: cannot open for appending: {exc}") from exc
            recover(path)
            f = h5py.File(path, "r+", libver="latest")
        f.swmr_mode = True
        writer = cls(f, path)
        writer._truncate_to_consistent()
        return writer

    def _truncate_to_consistent(self) -> None:
        """Valid rows are those with a frame; trim the block-extended rows to match."""
        n = min([self._frames.shape[0]] + [d.shape[0] for d in self._rows.values()])
        for d in [self._frames, *self._rows.values()]:
            if d.shape[0] != n:
                d.resize(n, axis=0)
        self.n = n
        self._rows_len = n
        self.f.flush()

    @property
    def capture_indices(self) -> np.ndarray:
        return self._rows[S.CAPTURE_INDEX][: self.n]

    def header_attr(self, name: str):
        return self.f.attrs[name]

    def append(self, frame: np.ndarray, **row) -> None:
        """One capture: the frame and its row (keys: the per-frame dataset names)."""
        i = self.n
        frames = self._frames
        if frame.shape != frames.shape[1:]:
            raise RunFileError(f"{self.path}: frame shape {frame.shape} differs from the run's {frames.shape[1:]}")
        # Rows first (their datasets grow a block at a time), the frame last: the
        # frame count is the number of valid rows, so a crash in between leaves a row
        # without a frame (trimmed on resume), never a frame without its wrench and pose.
        if self._rows_len <= i:
            for d in self._rows.values():
                d.resize(i + ROW_BLOCK, axis=0)
            self._rows_len = i + ROW_BLOCK
        for name, d in self._rows.items():
            d[i] = row[name]
        frames.resize(i + 1, axis=0)
        frames[i] = frame
        self.f.flush()
        self.n = i + 1

    def set_status(self, status: str, reason: str = "") -> None:
        self.f[S.STATUS][()] = np.bytes_(status[: S.STATUS_LEN])
        self.f[S.STATUS_REASON][()] = np.bytes_(reason.encode("utf-8")[: S.REASON_LEN])
        self.f.flush()

    def close(self) -> None:
        if self.f.id.valid:
            self._truncate_to_consistent()
            self.f.close()


def recover(path: Path) -> None:
    """Copy a crashed run (readable in SWMR mode) into a clean file that replaces it."""
    tmp = path.with_suffix(path.suffix + ".recovering")
    with h5py.File(path, "r", swmr=True) as src, h5py.File(tmp, "w", libver="latest") as dst:
        for key, value in src.attrs.items():
            dst.attrs[key] = value
        for key in src:
            src.copy(src[key], dst, name=key)
    os.replace(tmp, path)


def open_for_reading(path: str | Path) -> h5py.File:
    """A run file for reading, also while it is being written or after its writer crashed."""
    path = Path(path)
    if not path.exists():
        raise RunFileError(f"{path}: no such file")
    try:
        return h5py.File(path, "r", swmr=True)
    except OSError as exc:
        raise RunFileError(f"{path}: not a readable HDF5 run file ({exc})") from exc
