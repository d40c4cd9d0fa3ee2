"""How run files lie on disk: the creation filters of growing datasets, temp names and
atomic replacement.

Every growing dataset is created with ``chunked``; a new or rewritten file is written
under a temporary name beside the run (``RUN.h5.creating-PID``, ``.recovering-PID``,
``.compacting-PID``, ``.writing-PID``), fsynced, and renamed over the run only when complete, so a crash
never leaves a half-written file at the run's name. Call the helpers that touch a run's
temp files only while holding its writer lock (acquisition/writer_lock.py).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import h5py

from acquisition import schema as S
from acquisition.hdf5_open import open_swmr_read
from acquisition.run_layout import filter_ids

ROW_BLOCK = 256  # per-row datasets grow in blocks; the frame count says how many rows are valid
STREAM_BLOCK = 1024  # rows per chunk of a stream dataset: ~10 s of a 100 Hz gauge
# RUN.h5.creating-PID, ...; a whole run written by merge or import (acquisition/whole_run.py) too
TEMP_MARKS = (".creating-", ".recovering-", ".compacting-", ".writing-")


def chunked(chunks: tuple[int, ...], *, codec: str | None = None) -> dict:
    """Creation keywords of every growing dataset: the one place for its filters.

    Fletcher-32 stores a checksum per chunk, checked on every read. One frame per
    chunk keeps a damaged chunk to one frame; ``codec`` (frames: a name in the schema's
    FRAME_CODECS) adds that lossless codec, which h5py puts before the checksum, so the
    checksum covers the bytes on disk.
    """
    return {"chunks": chunks, "fletcher32": True, **(S.FRAME_CODECS[codec] if codec else {})}


def frames_codec(f: h5py.File) -> str | None:
    """The name (in the schema's CODEC_FILTER_IDS) of the codec ``f``'s frames are stored with;
    None when uncompressed (files before compression) or in a codec this version does not write."""
    ids = filter_ids(f[S.FRAMES])
    return next((name for name, fid in S.CODEC_FILTER_IDS.items() if fid in ids), None)


def temp_path(path: Path, mark: str) -> Path:
    return path.with_name(f"{path.name}{mark}{os.getpid()}")


def remove_stale_temps(path: Path) -> list[Path]:
    """Temp files a crashed writer of ``path`` left; call only while holding its lock."""
    stale = [
        p
        for p in path.parent.glob(f"{glob_escape(path.name)}.*-*")
        if any(p.name.startswith(path.name + mark) for mark in TEMP_MARKS)
    ]
    for p in stale:
        p.unlink(missing_ok=True)
    return stale


def glob_escape(name: str) -> str:
    return re.sub(r"([*?\[])", r"[\1]", name)


def fsync_path(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def recover(path: Path) -> None:
    """Copy a crashed run (readable in SWMR mode) into a clean file that replaces it.

    Call only while holding the run's writer lock.
    """
    tmp = temp_path(path, ".recovering-")
    try:
        with open_swmr_read(path) as src, h5py.File(tmp, "w", libver="latest") as dst:
            for key, value in src.attrs.items():
                dst.attrs[key] = value
            for key in src:
                src.copy(src[key], dst, name=key)
        fsync_path(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
