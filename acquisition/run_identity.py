"""A run file's identity: its size, its modification time and a hash of its header and chunk index.

``dataset split`` records it for every run it reads (after verifying the whole file); ``train``,
``evaluate`` and ``generate --split`` compare it before reading a frame, so a file changed since
its split was made (damaged, truncated, rewritten, resumed) is refused naming what changed,
instead of being read on the strength of a verification it no longer has.

The hash covers, without decoding a frame: every root attribute; every dataset's path, dtype,
shape, filters and attributes; the data of the small unchunked datasets (object image, reference
frame, status); and for every chunk of the growing datasets its position, address, stored size and
its four stored checksum bytes (Fletcher-32, acquisition/chunk_checksum.py). A byte changed in a
chunk changes either nothing HDF5 reads (then the next read of it fails its checksum) or, once
rewritten, its checksum bytes: the hash. Cost: ~10 ms for a 1,600-frame run. So a file whose
modification time changed is verified whole before its hash is compared (``changed_since``): the
hash and every chunk's checksum together vouch for every byte.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import h5py
import numpy as np

from acquisition.chunk_checksum import chunk_index, has_trailing_checksum
from acquisition.run_checks import first_line
from acquisition.run_reader import RunReader, open_for_reading
from acquisition.writer_lock import RunFileError

KEYS = ("size", "mtime_ns", "sha256")


def _value_bytes(value) -> bytes:
    arr = np.asarray(value)
    if arr.dtype.kind == "O":
        return repr([v.decode("utf-8", "replace") if isinstance(v, bytes) else str(v) for v in arr.ravel()]).encode()
    return arr.dtype.str.encode() + repr(arr.shape).encode() + arr.tobytes()


def _attrs(h: "hashlib._Hash", attrs: h5py.AttributeManager) -> None:
    for name in sorted(attrs):
        h.update(b"\0attr\0" + name.encode() + b"\0" + _value_bytes(attrs[name]))


def header_hash(path: Path, f: h5py.File) -> str:
    """sha256 of the header and chunk index (module docstring)."""
    h = hashlib.sha256()
    _attrs(h, f.attrs)
    names: list[str] = []
    f.visit(names.append)
    with open(path, "rb") as raw:
        for name in sorted(names):
            obj = f[name]
            h.update(b"\0object\0" + name.encode())
            _attrs(h, obj.attrs)
            if not isinstance(obj, h5py.Dataset):
                continue
            dcpl = obj.id.get_create_plist()
            filters = [dcpl.get_filter(i)[:2] for i in range(dcpl.get_nfilters())]
            h.update(f"{obj.dtype.str}|{obj.shape}|{obj.chunks}|{filters}".encode())
            if obj.chunks is None:
                h.update(_value_bytes(obj[()]))
                continue
            trailing = has_trailing_checksum(obj)
            for start, (address, size, mask) in sorted(chunk_index(obj).items()):
                h.update(f"|{start}:{address}:{size}:{mask}".encode())
                if trailing and size >= 4:
                    h.update(os.pread(raw.fileno(), 4, address + size - 4))
    return h.hexdigest()


def identity_of(path: Path, f: h5py.File) -> dict:
    """{size, mtime_ns, sha256} of the run at ``path``, open as ``f`` (already verified by the caller)."""
    stat = path.stat()
    try:
        digest = header_hash(path, f)
    except (OSError, RuntimeError, KeyError, ValueError) as exc:
        raise RunFileError(f"{path}: header or chunk index unreadable ({first_line(exc)})") from None
    return {"size": stat.st_size, "mtime_ns": stat.st_mtime_ns, "sha256": digest}


def identity(path: str | Path, *, whole: bool = False) -> dict:
    """{size, mtime_ns, sha256} of a run file; RunFileError when it cannot be read. ``whole``: the
    file verified whole first (the verified reader, every frame's checksum): RunFileError naming the
    damage, so that a matching hash then vouches for every byte of it (module docstring)."""
    path = Path(path)
    if not whole:
        with open_for_reading(path) as f:
            return identity_of(path, f)
    with RunReader.open(path) as run:
        run.verify_frames()
        return identity_of(path, run.f)


def changed_since(path: str | Path, recorded: dict) -> str:
    """What differs between the file now and its ``recorded`` identity, in words ("" when nothing).

    A file of another size is refused without being opened. A file of the same size and time is
    compared by its hash. Its modification time alone decides nothing: a copy (``cp`` without ``-p``,
    a backup restored) or ``touch`` changes it and nothing else. But a byte changed inside a chunk
    changes the time and not the hash (only HDF5's next read of that chunk fails its checksum), so a
    file written since is verified whole (every row, image and frame against its checksum) before
    its hash is compared: accepted only when both hold."""
    path = Path(path)
    try:
        stat = path.stat()
    except OSError as exc:
        return f"cannot be read now ({exc.strerror})"
    if stat.st_size != recorded["size"]:
        return f"its size is {stat.st_size:,} bytes, {recorded['size']:,} then"
    try:
        now = identity(path, whole=stat.st_mtime_ns != recorded["mtime_ns"])["sha256"]
    except RunFileError as exc:
        return str(exc).removeprefix(f"{path}: ")
    if now != recorded["sha256"]:
        when = "same size and time" if stat.st_mtime_ns == recorded["mtime_ns"] else "same size, written since"
        return f"its header or chunk index differs ({when})"
    return ""
