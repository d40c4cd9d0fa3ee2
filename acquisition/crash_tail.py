"""What ``--resume`` keeps of a run: everything that reached the disk, and nothing after damage.

A writer killed in the middle of an append leaves at most the end of each growing dataset
unwritten (acquisition/run_writer.py writes the stream, then the rows, then the frame, and counts
the frame after its flush): a frame whose chunk never reached the disk (absent from the chunk
index) or was cut short (it fails its checksum), and stream rows that were never written (a chunk
absent or cut short, or rows of HDF5's fill value, zeros, at the end of the last chunk). Such a
*tail* of a run whose writer crashed (status ``running``) is dropped: the crash left it uncounted.

Anything else is damage, refused naming the first damaged frame or stream rows: damage followed by
frames or rows that reached the disk (a crash cannot leave that), any damage in a run that was
closed (complete, aborted, interrupted), values the reader refuses. Appending to a damaged run
would bury the damage under new frames.
"""

from __future__ import annotations

import h5py
import numpy as np

from acquisition import schema as S
from acquisition.chunk_checksum import bad_chunks


def _rows(name: str, lo: int, hi: int) -> str:
    return f"{name}[{lo}]" if hi == lo else f"{name}[{lo}:{hi + 1}]"


def frames_kept(d: h5py.Dataset, n: int, crashed: bool) -> tuple[int, str]:
    """(frames to keep of the first ``n``, problem): the problem, naming the first damaged frame,
    when the damage is not a crashed run's tail (module docstring); "" when the frames can be kept.
    ChunkIndexError (acquisition/chunk_checksum.py) when the frames' chunk index is unreadable."""
    if d.chunks is None:  # contiguous frames (never written so): nothing can be missing
        return n, ""
    damaged = list(bad_chunks(d, n))
    tail = n
    for lo, hi, _ in reversed(damaged):  # the run of damaged frames that ends the file
        if hi != tail - 1:
            break
        tail = lo
    inside = [c for c in damaged if c[0] < tail]
    if inside or (damaged and not crashed):
        lo, hi, what = (inside or damaged)[0]
        return 0, f"{_rows(S.FRAMES, lo, hi)}: {what}"
    return tail, ""


def stream_kept(d: h5py.Dataset, crashed: bool) -> tuple[int, str]:
    """(rows of the full-rate stream to keep, problem): every row of a sound stream; a crashed run's
    rows before its unwritten tail; else the problem naming the first damaged rows (module docstring).
    ChunkIndexError when the stream's chunk index is unreadable."""
    name, m = d.name.lstrip("/"), d.shape[0]
    step = d.chunks[0] if d.chunks else max(m, 1)
    bad = {lo: (hi, what) for lo, hi, what in bad_chunks(d, m)} if d.chunks else {}
    tail: tuple[int, str] | None = None  # the first row that never reached the disk, and what showed it
    previous = -np.inf
    for lo in range(0, m, step):
        hi = min(lo + step, m)
        if lo in bad:
            last, what = bad[lo]
            if not crashed:
                return 0, f"{_rows(name, lo, last)}: {what}"
            tail = tail or (lo, f"{_rows(name, lo, last)}: {what}")
            continue
        rows = d[lo:hi]
        unwritten = ~rows.any(axis=1)  # HDF5's fill value: rows a crash left unwritten
        if tail is not None:
            if not unwritten.all():
                at = lo + int(np.argmin(unwritten))
                return 0, f"{tail[1]}, followed by rows that reached the disk (row {at})"
            continue
        finite = np.isfinite(rows).all(axis=1)
        back = rows[:, 0] < np.concatenate([[previous], rows[:-1, 0]])
        wrong = ~finite | back
        if wrong.any():
            j = int(np.argmax(wrong))
            if crashed and unwritten[j:].all():
                tail = (lo + j, f"{name}[{lo + j}:{hi}]: never written (zeros)")
                continue
            what = "NaN/inf" if not finite[j] else "time goes back"
            return 0, f"{name}: {what} at row {lo + j}"
        previous = rows[-1, 0] if len(rows) else previous
    return (m if tail is None else tail[0]), ""
