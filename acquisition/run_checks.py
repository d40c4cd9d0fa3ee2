"""What a run file's content must satisfy, as findings: one line each, starting with the dataset.

Shared by the verified reader (acquisition/run_reader.py: every command refuses a file with any of
these) and ``dataset validate`` (which lists them all, with its own judgements of the images and
the wrench–frame skew beside them), so what validate refuses, every reader refuses.
"""

from __future__ import annotations

from collections.abc import Callable

import h5py
import numpy as np

from acquisition import schema as S
from acquisition.chunk_checksum import ChunkIndexError, chunk_index


def first_line(exc: BaseException) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def metadata_problem(f: h5py.File) -> str:
    """ "" when the root group, its attributes and the frames' header read; else the damage in words.
    Checked first by every reader: damaged metadata costs one bounded SWMR retry (~0.3 s,
    acquisition/hdf5_open.py) here, instead of one per dataset and attribute."""
    try:
        names = set(f.keys())
        f.attrs.get(S.ATTR_SCHEMA)
        if S.FRAMES in names:
            f[S.FRAMES].dtype  # noqa: B018 (reads the dataset's header)
    except (OSError, RuntimeError, KeyError, ValueError) as exc:
        text = exc.args[0] if isinstance(exc, KeyError) and exc.args else first_line(exc)
        return f"unreadable metadata ({text})"
    return ""


def text_of(f: h5py.File, name: str) -> tuple[str, str]:
    """(a scalar bytes dataset as text, problem); problem "" when it reads as UTF-8."""
    try:
        raw = f[name][()]
    except (OSError, RuntimeError, KeyError, ValueError) as exc:
        return "", f"{name}: unreadable ({first_line(exc)})"
    raw = raw if isinstance(raw, bytes) else bytes(np.asarray(raw).tobytes())
    try:
        return raw.decode("utf-8"), ""
    except UnicodeDecodeError as exc:
        return "", f"{name}: not UTF-8 text (byte {exc.start}: {raw[exc.start : exc.start + 1]!r})"


def checksum_findings(f: h5py.File, sound: set[str]) -> tuple[list[str], list[str]]:
    """(findings, notes): every growing dataset checksummed, or none of them (an old file: a note)."""
    unprotected = [
        fl.path for fl in (S.FRAMES_FIELD, *S.PER_FRAME_FIELDS) if fl.path in sound and not f[fl.path].fletcher32
    ]
    if unprotected and len(unprotected) == 1 + len(S.PER_FRAME_FIELDS):
        return [], ["no checksums (old file): corruption inside a frame or row cannot be detected"]
    if unprotected:
        return [f"{unprotected[0]}: no checksum filter (Fletcher-32), unlike the rest of the file"], []
    return [], []


def status_findings(f: h5py.File, sound: set[str]) -> tuple[str, str, list[str]]:
    """(status, reason, findings about their form): status one of STATUSES, both UTF-8 text, the
    wrench's units stated. Whether the run completed is the caller's question."""
    findings = []
    status = reason = ""
    if S.STATUS in sound:
        status, problem = text_of(f, S.STATUS)
        if problem:
            findings.append(problem)
        elif status not in S.STATUSES:
            findings.append(f"{S.STATUS}: {status!r} is not one of {', '.join(S.STATUSES)}")
    if S.STATUS_REASON in sound:
        reason, problem = text_of(f, S.STATUS_REASON)
        if problem:
            findings.append(problem)
    if S.WRENCH in sound and "N·mm" not in str(f[S.WRENCH].attrs.get("units", "")):
        findings.append(f"{S.WRENCH}: units attribute missing or not N and N·mm")
    return status, reason, findings


def row_count_findings(f: h5py.File, sound: set[str], n: int, status: str) -> list[str]:
    """Every per-frame dataset has a row for each frame; once the run is closed (any status but
    ``running``: the writer trims its row blocks to the frames), exactly one."""
    findings = []
    for fl in (*S.PER_FRAME_FIELDS, S.FIELD[S.FRAME_DIGEST]):
        if fl.path not in sound:
            continue
        rows = f[fl.path].shape[0]
        if rows < n:
            findings.append(f"{fl.path}: {rows} rows for {n} frames")
        elif rows > n and status != "running":
            findings.append(f"{fl.path}: {rows} rows for {n} frames (a closed run has one row per frame)")
    return findings


def read_rows(f: h5py.File, names: list[str], n: int) -> tuple[dict[str, np.ndarray], list[str]]:
    """The first ``n`` rows of each dataset, read through HDF5 (every chunk's checksum checked);
    a damaged chunk is located and named with the frames it holds."""
    rows, findings = {}, []
    for name in names:
        d = f[name]
        try:
            rows[name] = d[:n]
        except (OSError, RuntimeError) as exc:
            index = _index_unreadable(d)
            if index:  # no chunk can be located: one line, not one failed read per chunk
                findings.append(f"{name}: {index}")
                continue
            step = d.chunks[0] if d.chunks else n
            where = ""
            for lo in range(0, n, step):
                try:
                    d[lo : min(lo + step, n)]
                except (OSError, RuntimeError):
                    where = f" in the rows of frames {lo}-{min(lo + step, n) - 1}"
                    break
            findings.append(f"{name}: unreadable{where}, checksum mismatch or missing bytes ({first_line(exc)})")
    return rows, findings


def _index_unreadable(d: h5py.Dataset) -> str:
    """The problem with ``d``'s chunk index in words; "" when it reads (or ``d`` is not chunked)."""
    if d.chunks is None:
        return ""
    try:
        chunk_index(d)
    except ChunkIndexError as exc:
        return str(exc)
    return ""


def row_findings(
    rows: dict[str, np.ndarray], n: int, phases: int | None, where: Callable[[int], str] = lambda i: f"frame {i}"
) -> list[str]:
    """Values every reader relies on: finite numbers, time increasing, the capture grid contiguous
    from 0, phases within the file's list (``phases``: its length; None when the list is missing),
    levels not negative. Each names the first frame where it fails (``where(i)`` words frame i: an
    import names its CSV row)."""
    findings: list[str] = []
    if n == 0:
        return findings
    for name, values in rows.items():
        if values.dtype.kind == "f":
            bad = ~np.isfinite(values.reshape(n, -1)).all(axis=1)
            if bad.any():
                at = np.nonzero(bad)[0]
                findings.append(f"{name}: NaN/inf in {len(at)} rows (first at {where(int(at[0]))})")
    for name in (S.T_FRAME, S.T_CAPTURE):
        if name in rows and n > 1 and np.any(np.diff(rows[name]) <= 0):
            k = int(np.argmax(np.diff(rows[name]) <= 0)) + 1
            findings.append(f"{name}: not increasing at {where(k)} ({rows[name][k]!r} after {rows[name][k - 1]!r})")
    if S.CAPTURE_INDEX in rows:
        idx = rows[S.CAPTURE_INDEX]
        if idx[0] != 0:
            findings.append(f"{S.CAPTURE_INDEX}: starts at {idx[0]}, expected 0")
        if n > 1 and np.any(np.diff(idx) != 1):
            findings.append(f"{S.CAPTURE_INDEX}: gap or duplicate at {where(int(np.argmax(np.diff(idx) != 1)) + 1)}")
    if S.PHASE_INDEX in rows and phases is not None:
        bad = (rows[S.PHASE_INDEX] < 0) | (rows[S.PHASE_INDEX] >= phases)
        if bad.any():
            first = int(np.argmax(bad))
            findings.append(
                f"{S.PHASE_INDEX}: {int(bad.sum())} rows outside the {phases} phases "
                f"(first at {where(first)}: {int(rows[S.PHASE_INDEX][first])})"
            )
    if S.LEVEL in rows and np.any(rows[S.LEVEL] < 0):
        findings.append(f"{S.LEVEL}: negative at {where(int(np.argmax(rows[S.LEVEL] < 0)))}")
    return findings


def read_stream(f: h5py.File, name: str) -> tuple[np.ndarray | None, list[str]]:
    """A full-rate stream, checked: every chunk readable, values finite, time never going back
    (samples that arrived in one read share its time stamp)."""
    try:
        rows = f[name][()]
    except (OSError, RuntimeError) as exc:
        problem = _index_unreadable(f[name]) or f"unreadable, checksum mismatch or missing bytes ({first_line(exc)})"
        return None, [f"{name}: {problem}"]
    findings: list[str] = []
    if rows.ndim != 2 or rows.shape[0] == 0:
        return rows, findings
    bad = ~np.isfinite(rows).all(axis=1)
    if bad.any():
        findings.append(f"{name}: NaN/inf in {int(bad.sum())} rows (first at row {int(np.argmax(bad))})")
    back = np.diff(rows[:, 0]) < 0
    if back.any():
        findings.append(f"{name}: time goes back at row {int(np.argmax(back)) + 1}")
    return rows, findings


def image_findings(f: h5py.File, sound: set[str]) -> tuple[dict[str, np.ndarray], list[str]]:
    """The object image and the reference frame, read (a checksummed one is verified)."""
    images, findings = {}, []
    for name in (S.OBJECT_IMAGE, S.REFERENCE_FRAME):
        if name in sound:
            try:
                images[name] = f[name][()]
            except (OSError, RuntimeError) as exc:
                findings.append(f"{name}: unreadable ({first_line(exc)})")
    return images, findings
