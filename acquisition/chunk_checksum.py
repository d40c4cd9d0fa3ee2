"""Every chunk of a dataset checked against its stored Fletcher-32 checksum, without decoding it.

HDF5's Fletcher-32 filter is the last of a chunk's pipeline when written (h5py puts it after the
compression filter), so the bytes on disk are the compressed chunk followed by its checksum: four
bytes, little-endian, the second sum in the high half (HDF5 source, H5Zfletcher32.c and
H5checksum.c). Reading a chunk's raw bytes (``read_direct_chunk``) and summing them here checks
the same thing HDF5 checks on a read, at the cost of reading the bytes: a split of a 1,600-frame
simulated run verifies its 209 MB in about a second, where decoding every frame takes as long
with Blosc and several times longer with HTJ2K (docs/run-file.md, "Verified reads").

A chunk that was never written is absent from the chunk index (a read would return fill zeros);
it is reported as missing, never taken for a frame. A chunk index that cannot be read (its metadata
fails HDF5's checksum) locates no chunk at all: ``ChunkIndexError``, one line for the dataset.
"""

from __future__ import annotations

from collections.abc import Iterator

import h5py
import numpy as np

FLETCHER32 = h5py.h5z.FILTER_FLETCHER32
MOD = 65535
BLOCK = 1 << 13  # words summed at once: small enough to reuse memory (a fresh large array costs page faults)


def fletcher32(body: bytes) -> tuple[int, int]:
    """HDF5's Fletcher-32 sums of ``body`` (16-bit big-endian words; an odd last byte is the high
    byte of a last word), each reduced modulo 65535 (HDF5 keeps either 0 or 65535 for zero). The
    second sum adds the running first sum after every word: per block, the block's running sums
    plus the first sum carried in once per word (exact in int64 for blocks of BLOCK words)."""
    words = np.frombuffer(body, ">u2", count=len(body) // 2)
    first = second = 0
    for lo in range(0, len(words), BLOCK):
        running = np.cumsum(words[lo : lo + BLOCK], dtype=np.int64)
        second = (second + len(running) * first + int(running.sum())) % MOD
        first = (first + int(running[-1])) % MOD
    if len(body) % 2:  # the odd last byte: one more word, its low byte zero
        first = (first + (body[-1] << 8)) % MOD
        second = (second + first) % MOD
    return first, second


def checksum_ok(raw: bytes) -> bool:
    """Do a chunk's raw bytes (data, then the four checksum bytes) agree with their checksum? HDF5
    also accepts the byte-swapped form written by versions before 1.6.3; so does this."""
    if len(raw) < 4:
        return False
    first, second = fletcher32(raw[:-4])
    stored = raw[-4:]
    as_written = (stored[0] | stored[1] << 8, stored[2] | stored[3] << 8)
    swapped = (stored[1] | stored[0] << 8, stored[3] | stored[2] << 8)
    return any(lo % MOD == first and hi % MOD == second for lo, hi in (as_written, swapped))


def has_trailing_checksum(d: h5py.Dataset) -> bool:
    """Is Fletcher-32 the dataset's last filter (so a raw chunk ends with its checksum)?"""
    dcpl = d.id.get_create_plist()
    n = dcpl.get_nfilters()
    return n > 0 and dcpl.get_filter(n - 1)[0] == FLETCHER32


class ChunkIndexError(ValueError):
    """A dataset's chunk index cannot be read (damaged metadata): no chunk of it can be located."""


def chunk_index(d: h5py.Dataset) -> dict[int, tuple[int, int, int]]:
    """{first row of the chunk: (byte offset, stored size, filter mask)} of every chunk on disk;
    ChunkIndexError when the index itself is unreadable."""
    found: dict[int, tuple[int, int, int]] = {}

    def add(info) -> None:
        found[int(info.chunk_offset[0])] = (int(info.byte_offset), int(info.size), int(info.filter_mask))

    try:
        d.id.chunk_iter(add)
    except (OSError, RuntimeError, ValueError) as exc:
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ChunkIndexError(f"chunk index unreadable ({text})") from None
    return found


def bad_chunks(d: h5py.Dataset, rows: int) -> Iterator[tuple[int, int, str]]:
    """(first row, last row, problem) of each chunk covering rows 0..rows-1 that is missing or fails
    its checksum. Datasets without a trailing checksum are read through HDF5 instead (a missing
    chunk is still found; corruption inside one cannot be, as in any file written before checksums).
    ChunkIndexError (before anything is yielded) when the chunk index cannot be read."""
    step = d.chunks[0]
    index = chunk_index(d)
    trailing = has_trailing_checksum(d)
    skipped = 1 << (d.id.get_create_plist().get_nfilters() - 1) if trailing else 0  # mask bit: checksum not applied
    origin = (0,) * (d.ndim - 1)
    for start in range(0, rows, step):
        last = min(start + step, rows) - 1
        if start not in index:
            yield start, last, "never written (no chunk on disk)"
            continue
        try:
            if trailing and not index[start][2] & skipped:
                _, raw = d.id.read_direct_chunk((start, *origin))
                if not checksum_ok(raw):
                    yield start, last, "checksum mismatch (its bytes changed on disk)"
            else:
                d[start : last + 1]
        except (OSError, RuntimeError, ValueError) as exc:
            text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            yield start, last, f"unreadable ({text})"
