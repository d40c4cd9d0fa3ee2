"""A checksum over a run file's root attributes, so that a relabelled or damaged attribute is found.

HDF5 stores variable-length text attributes (object_name, sensor_kind, phases, sensor_profile, the
protocol's and rig config's text) in its global heap, which has no checksum: a flipped byte, or
``sphere10mm`` edited into ``sphere15mm``, reads back without any error. So every file written
since keeps one more root attribute, ``attrs_sha256``: the SHA-256 of every other root attribute in
a canonical form (``canonical``), written at creation before SWMR mode forbids attribute changes
(acquisition/run_writer.py). A copy that carries every attribute over unchanged (a recovery after a
crash, ``dataset compact``) keeps a matching checksum; a file whose header is written anew (merge,
import) gets its own. ``--resume`` changes no root attribute.

The verified reader, ``--resume`` and ``dataset validate`` check it (``problem``). A file written
before the checksum existed has no ``attrs_sha256``: it stays readable as before, and validate
notes that its attributes cannot be checked (``NOTE``).
"""

from __future__ import annotations

import hashlib
import json

import h5py
import numpy as np

from acquisition import schema as S

NOTE = (
    f"no attribute checksum (written before {S.ATTR_ATTRS_SHA256} existed): a changed or damaged text "
    "attribute (object, sensor, profile, phases) cannot be detected"
)


def _plain(value) -> list:
    """[kind, value] of an attribute value as JSON can hold it exactly: text (bytes decoded, an
    undecodable byte kept as an escape), whole numbers, floats (repr: every bit; NaN as NaN)."""
    arr = np.asarray(value)
    if arr.dtype.kind in "OSU":
        text = [v.decode("utf-8", "surrogateescape") if isinstance(v, bytes) else str(v) for v in arr.ravel()]
        return ["text", list(arr.shape), text]
    if arr.dtype.kind in "iub":
        return [f"int{arr.dtype.kind}", list(arr.shape), [int(v) for v in arr.ravel()]]
    if arr.dtype.kind == "f":
        return ["float", list(arr.shape), [repr(float(v)) for v in arr.ravel()]]
    return [arr.dtype.str, list(arr.shape), arr.tobytes().hex()]


def canonical(attrs: h5py.AttributeManager) -> bytes:
    """Every root attribute but the checksum, sorted by name, as one JSON text."""
    items = [[name, _plain(attrs[name])] for name in sorted(attrs) if name != S.ATTR_ATTRS_SHA256]
    return json.dumps(items, ensure_ascii=True, separators=(",", ":")).encode("ascii")


def digest(attrs: h5py.AttributeManager) -> str:
    return hashlib.sha256(canonical(attrs)).hexdigest()


def seal(f: h5py.File) -> None:
    """Write the checksum of ``f``'s root attributes (after the last of them is written)."""
    f.attrs[S.ATTR_ATTRS_SHA256] = digest(f.attrs)


def problem(f: h5py.File) -> tuple[str, str]:
    """(finding, note): a finding when the attributes do not match their checksum; the note
    ``NOTE`` for a file written before the checksum; ("", "") when they match."""
    if S.ATTR_ATTRS_SHA256 not in f.attrs:
        return "", NOTE
    recorded = f.attrs[S.ATTR_ATTRS_SHA256]
    recorded = recorded.decode("utf-8", "replace") if isinstance(recorded, bytes) else str(recorded)
    if recorded != digest(f.attrs):
        return (
            f"attribute {S.ATTR_ATTRS_SHA256}: the root attributes do not match their checksum (an attribute was "
            "changed or damaged on disk since the file was written: object, sensor, profile, phases, protocol or "
            "rig config may not be what was recorded)",
            "",
        )
    return "", ""
