"""Frame identity: each frame and full-rate stream row bound to its index and its run (docs/run-file.md,
"Frame identity").

A chunk's Fletcher-32 checksum says its bytes are as written, not which frame they are: two frame
chunks swapped on disk (or a chunk copied from another run) each pass. So the writer keys a BLAKE2b
digest with the run's own random identity (``run_id``, a root attribute sealed with the others) and
hashes, per frame, its index, the frame's chunk exactly as stored (compressed, with its checksum:
a reader checks it without decoding) and its row of per-frame values; per stream row, its index
and its values. Every reader recomputes them (acquisition/run_reader.py) and refuses a frame or row
whose digest differs: a swapped, moved, duplicated or foreign chunk, or a row block moved with it.
Files written before digests have neither the identity nor the digests and are read as before.
"""

from __future__ import annotations

import hashlib
import secrets
from collections.abc import Mapping

import h5py
import numpy as np

from acquisition import schema as S

FRAME_DIGEST_BYTES = 16
STREAM_DIGEST_BYTES = 8


def new_run_id() -> str:
    """A run's identity: 128 random bits as 32 hex digits."""
    return secrets.token_hex(16)


def key_of(f: h5py.File) -> bytes | None:
    """The digests' key (the run's identity), None for a file written before digests."""
    run_id = f.attrs.get(S.ATTR_RUN_ID)
    if run_id is None:
        return None
    text = run_id.decode() if isinstance(run_id, bytes) else str(run_id)
    try:
        key = bytes.fromhex(text)
    except ValueError:
        return b""  # a damaged identity: no digest can match (the attribute checksum names it first)
    return key


def row_bytes(row: Mapping[str, object], fields=S.PER_FRAME_FIELDS) -> bytes:
    """One frame's per-frame values as stored: each field of the table in order, in its dtype."""
    parts = []
    for field in fields:
        if field.path in row:
            value = np.asarray(row[field.path], dtype=np.dtype(field.dtype).newbyteorder("<"))
            parts.append(np.ascontiguousarray(value).tobytes())
    return b"".join(parts)


def frame_digest(key: bytes, index: int, chunk: bytes, row: bytes) -> np.ndarray:
    """The digest of frame ``index``: its stored chunk and its row, keyed by the run."""
    h = hashlib.blake2b(key=key, digest_size=FRAME_DIGEST_BYTES)
    h.update(int(index).to_bytes(8, "little"))
    h.update(len(chunk).to_bytes(8, "little"))
    h.update(chunk)
    h.update(row)
    return np.frombuffer(h.digest(), dtype=np.uint8)


def stream_digests(key: bytes, first: int, rows: np.ndarray) -> np.ndarray:
    """(M,) uint64 digests of stream rows ``first``, ``first`` + 1, ... (their values as stored)."""
    data = np.ascontiguousarray(rows, dtype="<f8")
    out = np.empty(len(data), dtype=np.uint64)
    for j, row in enumerate(data):
        h = hashlib.blake2b(key=key, digest_size=STREAM_DIGEST_BYTES)
        h.update(int(first + j).to_bytes(8, "little"))
        h.update(row.tobytes())
        out[j] = int.from_bytes(h.digest(), "little")
    return out


def stored_chunk(frames: h5py.Dataset, index: int) -> bytes:
    """Frame ``index``'s chunk as stored (one frame per chunk)."""
    return frames.id.read_direct_chunk((index, *(0,) * (frames.ndim - 1)))[1]


def frame_mismatches(
    f: h5py.File, rows: Mapping[str, np.ndarray], n: int, chunks: Mapping[int, bytes] | None = None
) -> list[int]:
    """The frames of the first ``n`` whose digest differs from their chunk and row (empty for a file
    without digests). ``chunks``: raw chunks already read (index -> bytes), read here otherwise."""
    key = key_of(f)
    if key is None or S.FRAME_DIGEST not in f:
        return []
    digests = f[S.FRAME_DIGEST][:n]
    frames = f[S.FRAMES]
    bad = []
    for i in range(n):
        chunk = chunks[i] if chunks is not None and i in chunks else stored_chunk(frames, i)
        row = row_bytes({name: values[i] for name, values in rows.items()})
        if i >= len(digests) or not np.array_equal(frame_digest(key, i, chunk, row), digests[i]):
            bad.append(i)
    return bad


def stream_wrong(f: h5py.File, stream: np.ndarray) -> list[int]:
    """Every stream row whose digest differs from its values (empty: all agree, or no digests)."""
    key = key_of(f)
    if key is None or S.STREAM_DIGEST not in f or not len(stream):
        return []
    stored = np.zeros(len(stream), dtype=np.uint64)
    have = f[S.STREAM_DIGEST][: len(stream)]
    stored[: len(have)] = have
    return [int(j) for j in np.nonzero(stored != stream_digests(key, 0, stream))[0]]


def stream_mismatch(f: h5py.File, stream: np.ndarray) -> int | None:
    """The first stream row whose digest differs from its values (None: all agree, or no digests)."""
    key = key_of(f)
    if key is None or S.STREAM_DIGEST not in f or not len(stream):
        return None
    stored = f[S.STREAM_DIGEST][: len(stream)]
    expected = stream_digests(key, 0, stream)
    if len(stored) < len(expected):
        return len(stored)
    wrong = np.nonzero(stored != expected)[0]
    return int(wrong[0]) if len(wrong) else None
