"""Every frame of a run checked in one pass over its stored chunks, without decoding them: each chunk
present, as written (its Fletcher-32 checksum: acquisition/chunk_checksum.py) and in its place (its
identity digest: acquisition/frame_identity.py); the full-rate stream's rows against their digests.

What every reader runs when it opens a run (acquisition/run_reader.py), ``dataset validate`` and
``--resume`` too, so that a swapped, moved or zeroed chunk is refused by all of them alike.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import h5py
import numpy as np

from acquisition import schema as S
from acquisition.chunk_checksum import bad_chunks, checksum_ok, chunk_index, has_trailing_checksum
from acquisition.frame_identity import frame_digest, key_of, row_bytes, stream_mismatch

MOVED = "not the frame written at this index (its identity digest differs: rewritten, moved, swapped or copied)"


@dataclass
class FrameCheck:
    """The frames that failed (index -> what), in order."""

    bad: dict[int, str] = field(default_factory=dict)

    def findings(self) -> list[str]:
        """One line per kind of problem, naming its first frame and how many more."""
        by_kind: dict[str, list[int]] = {}
        for i, what in self.bad.items():
            by_kind.setdefault(what, []).append(i)
        lines = []
        for what, where in by_kind.items():
            more = f" and {len(where) - 1} more" if len(where) > 1 else ""
            lines.append(f"{S.FRAMES}[{where[0]}]: {what}{more}")
        return lines

    def tail_from(self, n: int) -> int:
        """The first frame of the damaged run of frames that ends the file (``n`` when the last is sound)."""
        tail = n
        while tail - 1 in self.bad:
            tail -= 1
        return tail


def check_frames(f: h5py.File, rows: Mapping[str, np.ndarray], n: int) -> FrameCheck:
    """Frames 0..n-1: present, checksum, digest (where the file has them). ChunkIndexError when the
    frames' chunk index cannot be read. Files whose frames carry no trailing checksum (written before
    checksums) are read through HDF5 for presence, and have no digests either."""
    d = f[S.FRAMES]
    out = FrameCheck()
    if n == 0:
        return out
    if d.chunks is None:
        try:
            d[:n]
        except (OSError, RuntimeError) as exc:
            out.bad[0] = f"unreadable ({str(exc).strip().splitlines()[0] if str(exc).strip() else exc})"
        return out
    if not has_trailing_checksum(d) or d.chunks[0] != 1:
        for lo, hi, what in bad_chunks(d, n):
            for i in range(lo, hi + 1):
                out.bad[i] = what
        return out
    index = chunk_index(d)
    skipped = 1 << (d.id.get_create_plist().get_nfilters() - 1)
    key = key_of(f)
    digests = f[S.FRAME_DIGEST][:n] if key is not None and S.FRAME_DIGEST in f else None
    origin = (0,) * (d.ndim - 1)
    for i in range(n):
        if i not in index:
            out.bad[i] = "never written (no chunk on disk)"
            continue
        try:
            _, raw = d.id.read_direct_chunk((i, *origin))
        except (OSError, RuntimeError, ValueError) as exc:
            out.bad[i] = f"unreadable ({str(exc).strip().splitlines()[0] if str(exc).strip() else exc})"
            continue
        if not index[i][2] & skipped and not checksum_ok(raw):
            out.bad[i] = "checksum mismatch (its bytes changed on disk)"
            continue
        if digests is not None and key is not None:
            row = row_bytes({name: values[i] for name, values in rows.items()})
            if i >= len(digests) or not np.array_equal(frame_digest(key, i, raw, row), digests[i]):
                out.bad[i] = MOVED
    return out


def stream_findings(f: h5py.File, stream: np.ndarray | None) -> list[str]:
    """The full-rate stream's rows against their digests: one line naming the first that differs."""
    if stream is None:
        return []
    j = stream_mismatch(f, stream)
    if j is None:
        return []
    return [f"{S.WRENCH_STREAM}[{j}]: not the row written at this index (its identity digest differs)"]
