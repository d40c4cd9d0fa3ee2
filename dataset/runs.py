"""Run files for the dataset tools: summaries (``dataset info``) and validation findings.

Uses only h5py and numpy (no torch), and SWMR reads, so it works on a file that is
still being written or whose writer crashed. Every file is opened through the verified
reader (acquisition/run_reader.py): a file it refuses is one RunFileError line naming the
file, the dataset and the frame; ``validate`` lists every finding instead, with the same
checks (acquisition/run_checks.py) and its own judgements of the frames and the skew.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from acquisition import attr_checksum
from acquisition import run_checks as C
from acquisition import schema as S
from acquisition.chunk_checksum import ChunkIndexError, chunk_index
from acquisition.frame_checks import MOVED, check_frames, stream_findings
from acquisition.run_layout import attr_problems, decode_phases, field_problems
from acquisition.run_reader import RunReader, open_for_reading
from acquisition.writer_lock import RunFileError
from common.wording import reason_only

FRAME_BATCH = 32  # frames read at once by validate: ~6 MB at 256x256


def open_run(path: str | Path) -> RunReader:
    """A run file, verified as every command reads one (acquisition/run_reader.py)."""
    return RunReader.open(path)


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
    sensor_profile: str = ""  # the recorded profile's record (name, sha256, file); "": none
    imported: str = ""  # for a run made by `dataset import`: its pose convention and image changes

    @property
    def profile_line(self) -> str:
        """The run's sensor profile in words: its name, hash and file, or that it has none."""
        return describe_profile(self.sensor_profile)


def describe_profile(record: str) -> str:
    """A recorded sensor profile (``SensorProfile.record()`` TOML) in one line; none: says so."""
    import tomllib

    if not record.strip():
        return "none recorded (a real sensor's run, or imported without --profile): physics renders need --profile"
    try:
        rec = tomllib.loads(record)
    except tomllib.TOMLDecodeError:
        return f"unreadable record {record[:40]!r}"
    sha = str(rec.get("sha256", "?"))
    return f"{rec.get('name', '?')} (sha256 {sha[:12]}…, file {rec.get('file') or '?'})"


def summarize(path: str | Path) -> RunSummary:
    with open_run(path) as run:
        return summary_of(run)


def summary_of(run: RunReader) -> RunSummary:
    """An open, verified run summarised (what ``dataset info`` prints)."""
    n = run.n
    w = run.rows[S.WRENCH]
    t = run.rows[S.T_FRAME]
    return RunSummary(
        path=str(run.path),
        frames=n,
        frames_planned=int(run.number(S.ATTR_FRAMES_PLANNED)),
        status=run.status,
        reason=run.reason,
        object_name=run.text(S.ATTR_OBJECT),
        sensor_kind=run.text(S.ATTR_SENSOR_KIND),
        protocol=run.text(S.ATTR_PROTOCOL_NAME),
        frame_shape=run.frame_shape,
        duration_s=float(t[-1] - t[0]) if n > 1 else 0.0,
        wrench_min=w.min(axis=0) if n else np.full(6, np.nan),
        wrench_max=w.max(axis=0) if n else np.full(6, np.nan),
        mm_per_px=run.number(S.ATTR_MM_PER_PX),
        sensor_profile=run.sensor_profile,
        imported=_imported(run.text(S.ATTR_RIG_CONFIG)),
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
            out.findings.append(f"file: unreadable ({C.first_line(exc)})")
    return out


def _check_open_run(f: h5py.File, out: Check, max_skew_s: float, sample_frames: int | None) -> None:
    damaged = C.metadata_problem(f)
    if damaged:  # nothing below would read either: one finding, not one per dataset
        out.findings.append(f"file: {damaged}")
        return
    problems = field_problems(f)
    out.findings += [f"{name}: {p}" for name, p in problems.items()]
    out.findings += [f"attribute {name}: {p}" for name, p in attr_problems(f).items()]
    finding, note = attr_checksum.problem(f)
    out.findings += [finding] if finding else []
    out.notes += [note] if note else []
    sound = {fl.path for fl in S.FIELDS if fl.path not in problems and fl.path in f}  # optional ones may be absent
    findings, notes = C.checksum_findings(f, sound)
    out.findings += findings
    out.notes += notes
    status, reason, findings = C.status_findings(f, sound)
    out.findings += findings
    if S.STATUS in sound and status in S.STATUSES and status != "complete":
        out.findings.append(f"{S.STATUS}: {status!r}, not complete ({reason_only(status, reason) or 'no reason'})")
        if not reason and S.STATUS_REASON in sound and status != "running":
            out.findings.append(f"{S.STATUS_REASON}: empty, but a run that stopped early must say why")
    n = f[S.FRAMES].shape[0] if S.FRAMES in sound else 0
    out.findings += C.row_count_findings(f, sound, n, status)
    short = {fl.path for fl in S.PER_FRAME_FIELDS if fl.path in sound and f[fl.path].shape[0] < n}
    if S.FRAMES in sound and n == 0:
        out.findings.append(f"{S.FRAMES}: no frames")
        return
    names = [fl.path for fl in S.PER_FRAME_FIELDS if fl.path in sound and fl.path not in short]
    rows, findings = C.read_rows(f, names, n)
    out.findings += findings
    whole_rows = not findings and all(fl.path in rows for fl in S.PER_FRAME_FIELDS)  # what a frame's digest covers
    phases = decode_phases(f) if S.ATTR_PHASES in f.attrs else None
    out.findings += C.row_findings(rows, n, None if phases is None else len(phases))
    if S.WRENCH_SKEW in rows:
        skew = rows[S.WRENCH_SKEW]
        if np.any(skew > max_skew_s):
            out.findings.append(
                f"{S.WRENCH_SKEW}: {int((skew > max_skew_s).sum())} frames beyond {max_skew_s} s "
                f"(max {np.nanmax(skew):.3f} s)"
            )
    for fl in S.STREAM_FIELDS:
        if fl.path in sound:
            stream, found = C.read_stream(f, fl.path)
            out.findings += found or stream_findings(f, stream)
    if S.FRAMES in sound:
        _check_frames(f[S.FRAMES], n, sample_frames, out)
        if whole_rows and sample_frames is None:  # each frame in its place (acquisition/frame_identity.py)
            try:
                moved = check_frames(f, rows, n)
            except ChunkIndexError:
                moved = None  # said by _check_frames
            if moved is not None:
                out.findings += [line for line in moved.findings() if MOVED in line]
    out.findings += C.image_findings(f, sound)[1]


def _check_frames(frames: h5py.Dataset, n: int, sample_frames: int | None, out: Check) -> None:
    """Read frames (all, or an even sample): checksums, and black, constant or saturated images.
    A chunk index that cannot be read is one finding (each frame's read would fail on it, slowly)."""
    if frames.chunks is not None:
        try:
            chunk_index(frames)
        except ChunkIndexError as exc:
            out.findings.append(f"{S.FRAMES}: {exc}")
            return
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
