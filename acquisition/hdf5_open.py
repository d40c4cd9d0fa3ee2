"""Opening HDF5 files so that a broken one fails in milliseconds, naming the file.

Two problems with plain ``h5py.File(path, "r", swmr=True)`` on a damaged file:

* A SWMR reader retries every metadata read whose checksum fails, on the theory that
  the writer is half-way through updating it, waiting twice as long after each try:
  with HDF5's default of 100 tries a file truncated to 1 % kept ``dataset info``
  asleep for over 20 minutes. A writer rewrites a piece of metadata within
  milliseconds, so ``READ_ATTEMPTS`` tries (about 0.3 s of waiting in all, measured
  with HDF5 2.0) are plenty; h5py has no wrapper for H5Pset_metadata_read_attempts,
  so it is called through ctypes on the HDF5 library h5py has already loaded.
* A file cut short can open without any error and read its missing end as zeros.
  The superblock stores the file's end-of-file address; a file shorter than that
  lost its end (HDF5 format spec, "Superblock", versions 0 to 3).
"""

from __future__ import annotations

import ctypes
import os
import struct
from functools import lru_cache
from pathlib import Path

import h5py
from h5py._objects import phil  # h5py's lock around the HDF5 library

READ_ATTEMPTS = 28

SIGNATURE = b"\x89HDF\r\n\x1a\n"
UNDEFINED = 0xFFFFFFFFFFFFFFFF


@lru_cache(maxsize=1)
def _set_read_attempts():
    """H5Pset_metadata_read_attempts of the HDF5 library h5py loaded, or None if not found."""
    try:
        with open("/proc/self/maps") as maps:
            libs = {line.split()[-1] for line in maps if "/libhdf5" in line and "_hl" not in line.rsplit("/", 1)[-1]}
        for lib in sorted(libs):
            library = ctypes.CDLL(lib, mode=os.RTLD_NOLOAD)  # the already-loaded copy
            fn = library.H5Pset_metadata_read_attempts
            fn.argtypes, fn.restype = [ctypes.c_int64, ctypes.c_uint], ctypes.c_int
            return fn
    except (OSError, AttributeError):
        pass
    return None  # another platform or build: HDF5's default retries, the size check still applies


def stored_size(path: Path) -> tuple[int | None, str]:
    """(end-of-file address the superblock records, problem) — problem is "" when the header reads."""
    with open(path, "rb") as fh:
        head = fh.read(256)
    if len(head) < 8 or head[:8] != SIGNATURE:
        return None, "not an HDF5 file (no HDF5 signature at the start)"
    if len(head) < 12:
        return None, f"truncated header: the file is {len(head)} bytes"
    version = head[8]
    if version in (0, 1):
        size_of_offsets = head[13]
        at = 24 + (4 if version == 1 else 0) + 2 * size_of_offsets  # base, free-space addresses before EOF
    elif version in (2, 3):
        size_of_offsets = head[9]
        at = 12 + 2 * size_of_offsets  # base, superblock-extension addresses before EOF
    else:
        return None, ""  # a newer superblock: leave the judgement to HDF5
    if size_of_offsets != 8:
        return None, ""
    if len(head) < at + 8:
        return None, f"truncated header: the file is {len(head)} bytes"
    (eof,) = struct.unpack_from("<Q", head, at)
    return (None if eof == UNDEFINED else eof), ""


def check_complete(path: Path) -> str:
    """'' when the file is at least as long as its superblock says, else the problem in words."""
    eof, problem = stored_size(path)
    if problem:
        return problem
    size = path.stat().st_size
    if eof is not None and size < eof:
        return f"truncated: {size:,} of its {eof:,} bytes are there (the end of the file is missing)"
    return ""


def _bounded_fapl(low: int) -> h5py.h5p.PropFAID:
    # The HDF5 library h5py bundles is not thread-safe: h5py holds its own lock (``phil``) around every
    # call into it. The read-attempts setter goes around h5py (ctypes), so it holds that lock too:
    # without it, a console thread reading one run while another opened one corrupted HDF5's state
    # ("can't decrement id ref count", a segfault in CI).
    with phil:
        fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
        fapl.set_libver_bounds(low, h5py.h5f.LIBVER_LATEST)
        setter = _set_read_attempts()
        if setter is not None:
            setter(fapl.id, READ_ATTEMPTS)
    return fapl


def open_swmr_read(path: Path) -> h5py.File:
    """``h5py.File(path, "r", swmr=True)`` with a bounded number of metadata read attempts."""
    fapl = _bounded_fapl(h5py.h5f.LIBVER_EARLIEST)
    fid = h5py.h5f.open(str(path).encode(), h5py.h5f.ACC_RDONLY | h5py.h5f.ACC_SWMR_READ, fapl=fapl)
    return h5py.File(fid)


def open_append(path: Path) -> h5py.File:
    """``h5py.File(path, "r+", libver="latest")`` with a bounded number of metadata read attempts.

    The bound holds until the file enters SWMR write mode (``swmr_mode = True``): from then on HDF5
    retries a metadata read whose checksum fails without end (a damaged chunk index kept
    ``--resume`` asleep until kill -9), so a file is verified read-only before it is opened this way
    (acquisition/run_resume.py)."""
    fapl = _bounded_fapl(h5py.h5f.LIBVER_LATEST)
    return h5py.File(h5py.h5f.open(str(path).encode(), h5py.h5f.ACC_RDWR, fapl=fapl))
