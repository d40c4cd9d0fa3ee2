"""Does an open run file have every dataset and attribute the schema table promises?

Shape and dtype only (no data is read), so it is cheap enough for every open. Used by
``--resume`` before appending, by the dataset tools before reading and by
``dataset validate``; each problem is one line that starts with the dataset's path.
"""

from __future__ import annotations

import h5py
import numpy as np

from acquisition import schema as S
from common.sensors import SENSOR_KINDS

NUMBER_KINDS = "iuf"


def _first_line(exc: BaseException) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def _dtype_ok(actual: np.dtype, expected: str) -> bool:
    want = np.dtype(expected)
    if want.kind == "S":  # fixed-length bytes; any length reads the same way
        return actual.kind == "S"
    return actual == want


def field_problems(f: h5py.File) -> dict[str, str]:
    """{dataset path: what is wrong} for every field of the table that is missing or malformed."""
    problems: dict[str, str] = {}
    for field in S.FIELDS:
        try:
            obj = f.get(field.path)
            if isinstance(obj, h5py.Dataset):
                obj.dtype, obj.shape  # noqa: B018 (reads the dataset's header: damage shows here)
        except (OSError, RuntimeError, KeyError, ValueError) as exc:
            problems[field.path] = f"unreadable ({_first_line(exc)})"
            continue
        if obj is None:
            if field.required:
                problems[field.path] = "missing"
            continue
        if not isinstance(obj, h5py.Dataset):
            problems[field.path] = f"is a {type(obj).__name__}, expected a dataset"
            continue
        if not _dtype_ok(obj.dtype, field.dtype):
            problems[field.path] = f"dtype {obj.dtype}, expected {np.dtype(field.dtype)}"
            continue
        shape = obj.shape[1:] if field.per_frame else obj.shape
        if field.per_frame and obj.ndim == 0:
            problems[field.path] = f"is a scalar, expected (N, {', '.join(map(str, field.shape))})"
        elif len(shape) != len(field.shape) or any(w is not None and a != w for a, w in zip(shape, field.shape)):
            want = ", ".join("any" if w is None else str(w) for w in field.shape)
            want = f"(N{', ' if want else ''}{want})" if field.per_frame else f"({want})"
            problems[field.path] = f"shape {obj.shape}, expected {want}"
    return problems


def _describe(value: np.ndarray) -> str:
    if value.ndim == 0:
        text = repr(value.item())
        return text if len(text) <= 40 else text[:37] + "..."
    return f"{value.dtype} array of shape {value.shape}"


def attr_problems(f: h5py.File) -> dict[str, str]:
    """{attribute name: what is wrong} for the root attributes of the table."""
    problems: dict[str, str] = {}
    optional = {name for name, _ in S.OPTIONAL_ATTRS}
    for name, kind in (*S.ATTRS, *S.OPTIONAL_ATTRS):
        try:
            if name not in f.attrs:
                if name not in optional:  # files written before an optional attribute existed lack it
                    problems[name] = "missing"
                continue
            value = np.asarray(f.attrs[name])
        except (OSError, RuntimeError, KeyError, ValueError) as exc:
            problems[name] = f"unreadable ({_first_line(exc)})"
            continue
        if kind == "str" and not (value.ndim == 0 and value.dtype.kind in "OSU"):
            problems[name] = f"is {_describe(value)}, expected text"
        elif kind in ("float", "int") and not (value.ndim == 0 and value.dtype.kind in NUMBER_KINDS):
            problems[name] = f"is {_describe(value)}, expected a number"
        elif kind == "int" and value.dtype.kind == "f" and not float(value).is_integer():
            problems[name] = f"is {value}, expected a whole number"
        elif kind == "float[4]" and not (value.shape == (4,) and value.dtype.kind in NUMBER_KINDS):
            problems[name] = f"is {_describe(value)}, expected 4 numbers"
        elif kind == "str[]" and not (value.ndim == 1 and value.dtype.kind in "OSU"):
            problems[name] = f"is {_describe(value)}, expected a list of text"
        elif name == S.ATTR_SENSOR_KIND and _text(value) not in SENSOR_KINDS:
            problems[name] = f"is {_describe(value)}, expected one of {', '.join(SENSOR_KINDS)}"
    return problems


def _text(value: np.ndarray) -> str:
    item = value.item()
    return item.decode("utf-8", "replace") if isinstance(item, bytes) else str(item)


def decode_phases(f: h5py.File) -> tuple[str, ...]:
    """The file's own ``phases`` attribute as text: ``phase_index`` indexes this list, never
    the code's list of phases (which may be in another order, or longer, than when the file
    was written). Empty when the attribute is missing (``attr_problems`` says so)."""
    value = f.attrs.get(S.ATTR_PHASES)
    if value is None:
        return ()
    return tuple(v.decode() if isinstance(v, bytes) else str(v) for v in np.atleast_1d(value))


def phase_names(f: h5py.File, indices: np.ndarray) -> list[str]:
    """``phase_index`` values decoded through the file's ``phases``; an index outside it is
    "?" (validate reports it)."""
    phases = decode_phases(f)
    return [phases[i] if 0 <= i < len(phases) else "?" for i in (int(v) for v in indices)]


def layout_problems(f: h5py.File) -> list[str]:
    """Every dataset and attribute problem as 'path: problem' lines (empty when the layout is sound)."""
    return (
        [f"{path}: {p}" for path, p in field_problems(f).items()]
        + [f"attribute {name}: {p}" for name, p in attr_problems(f).items()]
        + [f"{S.FRAMES}: {p}" for p in frame_filter_problems(f)]
    )


def filter_ids(d: h5py.Dataset) -> list[int]:
    """HDF5's ids of the filters ``d`` is stored with, in pipeline order."""
    dcpl = d.id.get_create_plist()
    return [dcpl.get_filter(i)[0] for i in range(dcpl.get_nfilters())]


def frame_filter_problems(f: h5py.File) -> list[str]:
    """The frames' filters this installation cannot apply, in words (a codec's plugin missing:
    every frame would fail to read, which must not pass for frames that never reached the disk)."""
    try:
        d = f.get(S.FRAMES)
        if not isinstance(d, h5py.Dataset):
            return []
        ids = filter_ids(d)
    except (OSError, RuntimeError, KeyError, ValueError):
        return []  # a damaged header: field_problems names it
    names = {fid: name for name, fid in S.CODEC_FILTER_IDS.items()}
    problems = []
    for fid in ids:
        if not h5py.h5z.filter_avail(fid):
            problems.append(
                f"stored with {names.get(fid, 'a codec')} (HDF5 filter {fid}), which this installation cannot "
                "decode: install hdf5plugin 7.1 or later (pip install 'hdf5plugin>=7.1')"
            )
    return problems
