"""Reading run files for the dataset tools: summaries and validation findings.

Uses only h5py and numpy (no torch), and SWMR reads, so it works on a file that is
still being written or whose writer crashed. Every problem is a RunFileError (or a
finding) of one line naming the file and the dataset.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from acquisition import schema as S
from acquisition.run_file import RunFileError, open_for_reading
from acquisition.run_layout import attr_problems, field_problems

FRAME_BATCH = 32  # frames read at once by validate: ~6 MB at 256x256


def open_run(path: str | Path) -> h5py.File:
    """Open a run file for reading; a one-line RunFileError for anything that is not a sound one."""
    path = Path(path)
    f = open_for_reading(path)
    problems = field_problems(f)
    missing = [name for name, p in problems.items() if p == "missing"]
    if missing:
        f.close()
        raise RunFileError(f"{path}: not a run file: missing {', '.join(missing)}")
    if problems:
        f.close()
        raise RunFileError(f"{path}: malformed run file: " + "; ".join(f"{k}: {v}" for k, v in problems.items()))
    return f


def read(f: h5py.File, name: str, sel=()) -> np.ndarray:
    """``f[name][sel]``; a damaged chunk (failed checksum, missing bytes) is a RunFileError."""
    try:
        return f[name][sel]
    except (OSError, RuntimeError) as exc:
        raise RunFileError(
            f"{f.filename}: {name}: unreadable ({str(exc).strip().splitlines()[0]}); "
            "the file is damaged (dataset validate lists what)"
        ) from None


@dataclass(frozen=True)
class RunSummary:
    path: str
    frames: int
    frames_planned: int
    status: str
    reason: str
    object_name: str
    sensor_kind: str
    protocol: str
    frame_shape: tuple[int, int, int]
    duration_s: float
    wrench_min: np.ndarray
    wrench_max: np.ndarray
    mm_per_px: float
    imported: str = ""  # for a run made by `dataset import`: its pose convention and image changes


def summarize(path: str | Path) -> RunSummary:
    with open_run(path) as f:
        n = f[S.FRAMES].shape[0]
        rows = [f[name].shape[0] for name in (S.WRENCH, S.T_FRAME)]
        n = min([n, *rows])
        w = read(f, S.WRENCH, slice(0, n)) if n else np.zeros((0, 6))
        t = read(f, S.T_FRAME, slice(0, n))
        a = f.attrs
        return RunSummary(
            path=str(path),
            frames=n,
            frames_planned=int(a.get(S.ATTR_FRAMES_PLANNED, n)),
            status=read(f, S.STATUS).item().decode(errors="replace"),
            reason=read(f, S.STATUS_REASON).item().decode(errors="replace"),
            object_name=str(a.get(S.ATTR_OBJECT, "?")),
            sensor_kind=str(a.get(S.ATTR_SENSOR_KIND, "?")),
            protocol=str(a.get(S.ATTR_PROTOCOL_NAME, "?")),
            frame_shape=tuple(f[S.FRAMES].shape[1:]),
            duration_s=float(t[-1] - t[0]) if n > 1 else 0.0,
            wrench_min=w.min(axis=0) if n else np.full(6, np.nan),
            wrench_max=w.max(axis=0) if n else np.full(6, np.nan),
            mm_per_px=float(a.get(S.ATTR_MM_PER_PX, np.nan)),
            imported=_imported(str(a.get(S.ATTR_RIG_CONFIG, ""))),
        )


def _imported(rig_config: str) -> str:
    """What `dataset import` recorded in rig_config after its first line ("imported from FOLDER"):
    the folder's stated pose convention, the axes it flipped, the images' crop, pad or resize."""
    lines = rig_config.splitlines()
    if not lines or not lines[0].startswith("imported from "):
        return ""
    return "; ".join([lines[0].removeprefix("imported from "), *lines[1:]])


@dataclass
class Check:
    """What validate found: findings fail a run, notes do not."""

    findings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def validate(path: str | Path, *, max_skew_s: float = 0.1, sample_frames: int | None = None) -> list[str]:
    """Findings, one line each starting with the dataset (empty when the run is sound)."""
    return check_run(path, max_skew_s=max_skew_s, sample_frames=sample_frames).findings


def check_run(path: str | Path, *, max_skew_s: float = 0.1, sample_frames: int | None = None) -> Check:
    """Everything the schema promises (docs/run-file.md, "What validate checks").

    Every frame is read (so every chunk's checksum is checked) unless ``sample_frames``
    asks for that many evenly spaced frames; the rows are always read in full.
    """
    out = Check()
    try:
        f = open_for_reading(path)
    except RunFileError as exc:
        out.findings.append(f"file: {str(exc).removeprefix(f'{path}: ')}")
        return out
    with f:
        try:
            _check_open_run(f, out, max_skew_s, sample_frames)
        except (OSError, RuntimeError, KeyError, ValueError) as exc:  # damage beyond what the checks expect
            out.findings.append(f"file: unreadable ({_line(exc)})")
    return out


def _check_open_run(f: h5py.File, out: Check, max_skew_s: float, sample_frames: int | None) -> None:
    problems = field_problems(f)
    out.findings += [f"{name}: {p}" for name, p in problems.items()]
    out.findings += [f"attribute {name}: {p}" for name, p in attr_problems(f).items()]
    sound = {fl.path for fl in S.FIELDS if fl.path not in problems and fl.path in f}  # optional ones may be absent
    _check_checksums(f, sound, out)
    _check_status(f, sound, out)
    n = f[S.FRAMES].shape[0] if S.FRAMES in sound else 0
    for fl in S.PER_FRAME_FIELDS:
        if fl.path in sound and f[fl.path].shape[0] < n:
            out.findings.append(f"{fl.path}: {f[fl.path].shape[0]} rows for {n} frames")
            sound.discard(fl.path)
    if S.FRAMES in sound and n == 0:
        out.findings.append(f"{S.FRAMES}: no frames")
        return
    rows = {}
    for fl in S.PER_FRAME_FIELDS:
        if fl.path in sound:
            try:
                rows[fl.path] = f[fl.path][:n]
            except (OSError, RuntimeError) as exc:
                out.findings.append(f"{fl.path}: unreadable, checksum mismatch or missing bytes ({_line(exc)})")
    _check_rows(f, rows, n, max_skew_s, out)
    for fl in S.STREAM_FIELDS:
        if fl.path in sound:
            _check_stream(f, fl.path, out)
    if S.FRAMES in sound:
        _check_frames(f[S.FRAMES], n, sample_frames, out)
    for name in (S.OBJECT_IMAGE, S.REFERENCE_FRAME):
        if name in sound:
            try:
                f[name][()]
            except (OSError, RuntimeError) as exc:
                out.findings.append(f"{name}: unreadable ({_line(exc)})")


def _line(exc: BaseException) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def _check_checksums(f: h5py.File, sound: set[str], out: Check) -> None:
    unprotected = [
        fl.path for fl in (S.FRAMES_FIELD, *S.PER_FRAME_FIELDS) if fl.path in sound and not f[fl.path].fletcher32
    ]
    if unprotected and len(unprotected) == 1 + len(S.PER_FRAME_FIELDS):
        out.notes.append("no checksums (old file): corruption inside a frame or row cannot be detected")
    elif unprotected:
        out.findings.append(f"{unprotected[0]}: no checksum filter (Fletcher-32), unlike the rest of the file")


def _check_status(f: h5py.File, sound: set[str], out: Check) -> None:
    if S.STATUS not in sound:
        return
    status = f[S.STATUS][()].decode(errors="replace")
    reason = f[S.STATUS_REASON][()].decode(errors="replace") if S.STATUS_REASON in sound else ""
    if status not in S.STATUSES:
        out.findings.append(f"{S.STATUS}: {status!r} is not one of {', '.join(S.STATUSES)}")
    elif status != "complete":
        out.findings.append(f"{S.STATUS}: {status!r}, not complete ({reason or 'no reason'})")
        if not reason and S.STATUS_REASON in sound and status != "running":
            out.findings.append(f"{S.STATUS_REASON}: empty, but a run that stopped early must say why")
    if S.WRENCH in sound and "N·mm" not in str(f[S.WRENCH].attrs.get("units", "")):
        out.findings.append(f"{S.WRENCH}: units attribute missing or not N and N·mm")


def _check_rows(f: h5py.File, rows: dict[str, np.ndarray], n: int, max_skew_s: float, out: Check) -> None:
    for name, values in rows.items():
        if values.dtype.kind == "f":
            bad = ~np.isfinite(values.reshape(n, -1)).all(axis=1)
            if bad.any():
                rows_bad = np.nonzero(bad)[0]
                out.findings.append(f"{name}: NaN/inf in {len(rows_bad)} rows (first at frame {rows_bad[0]})")
    for name in (S.T_FRAME, S.T_CAPTURE):
        if name in rows and n > 1 and np.any(np.diff(rows[name]) <= 0):
            out.findings.append(f"{name}: not increasing at frame {int(np.argmax(np.diff(rows[name]) <= 0)) + 1}")
    if S.CAPTURE_INDEX in rows:
        idx = rows[S.CAPTURE_INDEX]
        if idx[0] != 0:
            out.findings.append(f"{S.CAPTURE_INDEX}: starts at {idx[0]}, expected 0")
        if n > 1 and np.any(np.diff(idx) != 1):
            out.findings.append(f"{S.CAPTURE_INDEX}: gap or duplicate at frame {int(np.argmax(np.diff(idx) != 1)) + 1}")
    if S.PHASE_INDEX in rows and S.ATTR_PHASES in f.attrs:
        phases = len(np.atleast_1d(f.attrs[S.ATTR_PHASES]))
        bad = (rows[S.PHASE_INDEX] < 0) | (rows[S.PHASE_INDEX] >= phases)
        if bad.any():
            out.findings.append(
                f"{S.PHASE_INDEX}: {int(bad.sum())} rows outside the {phases} phases "
                f"(first at frame {int(np.argmax(bad))})"
            )
    if S.LEVEL in rows and np.any(rows[S.LEVEL] < 0):
        out.findings.append(f"{S.LEVEL}: negative at frame {int(np.argmax(rows[S.LEVEL] < 0))}")
    if S.WRENCH_SKEW in rows:
        skew = rows[S.WRENCH_SKEW]
        if np.any(skew > max_skew_s):
            out.findings.append(
                f"{S.WRENCH_SKEW}: {int((skew > max_skew_s).sum())} frames beyond {max_skew_s} s "
                f"(max {np.nanmax(skew):.3f} s)"
            )


def _check_stream(f: h5py.File, name: str, out: Check) -> None:
    """A full-rate stream: every chunk readable, values finite, time never going back (samples
    that arrived in one read share its time stamp)."""
    try:
        rows = f[name][()]
    except (OSError, RuntimeError) as exc:
        out.findings.append(f"{name}: unreadable, checksum mismatch or missing bytes ({_line(exc)})")
        return
    bad = ~np.isfinite(rows).all(axis=1)
    if bad.any():
        out.findings.append(f"{name}: NaN/inf in {int(bad.sum())} rows (first at row {int(np.argmax(bad))})")
    back = np.diff(rows[:, 0]) < 0
    if back.any():
        out.findings.append(f"{name}: time goes back at row {int(np.argmax(back)) + 1}")


def _check_frames(frames: h5py.Dataset, n: int, sample_frames: int | None, out: Check) -> None:
    """Read frames (all, or an even sample): checksums, and black, constant or saturated images."""
    if sample_frames is None:
        wanted = np.arange(n)
    else:
        wanted = np.unique(np.linspace(0, n - 1, min(n, sample_frames)).astype(int))
    seen: dict[str, list[int]] = {"unreadable": [], "all black": [], "constant": [], "saturated": []}
    for start in range(0, len(wanted), FRAME_BATCH):
        batch = wanted[start : start + FRAME_BATCH]
        try:  # contiguous batches in one read; a failure is located frame by frame
            imgs = frames[batch[0] : batch[-1] + 1] if sample_frames is None else None
        except (OSError, RuntimeError):
            imgs = None
        for j, i in enumerate(batch):
            if imgs is not None:
                img = imgs[j]
            else:
                try:
                    img = frames[int(i)]
                except (OSError, RuntimeError):
                    seen["unreadable"].append(int(i))
                    continue
            lo, hi = int(img.min()), int(img.max())
            if hi < 8:
                seen["all black"].append(int(i))
            elif lo == hi:
                seen["constant"].append(int(i))
            elif (img >= 250).mean() > 0.5:
                seen["saturated"].append(int(i))
    for kind, where in seen.items():
        if where:
            more = f" and {len(where) - 1} more" if len(where) > 1 else ""
            what = "checksum mismatch or missing bytes" if kind == "unreadable" else kind
            out.findings.append(f"frames[{where[0]}]: {what}{more}")
    if sample_frames is not None and len(wanted) < n:
        out.notes.append(f"frames: {len(wanted)} of {n} checked (--sample); run without it to check every frame")
