"""Reading run files for the dataset tools: summaries and validation findings.

Uses only h5py and numpy (no torch), and SWMR reads, so it works on a file that is
still being written or whose writer crashed.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from acquisition import schema as S
from acquisition.run_file import RunFileError

REQUIRED = (S.FRAMES, S.WRENCH, S.POSE_COMMANDED, S.POSE_MEASURED, S.T_FRAME, S.WRENCH_SKEW, S.CAPTURE_INDEX,
            S.OBJECT_IMAGE, S.STATUS)


def open_run(path: str | Path) -> h5py.File:
    """Open a run file for reading; a clear RunFileError for anything that is not one."""
    path = Path(path)
    if not path.exists():
        raise RunFileError(f"{path}: no such file")
    if not h5py.is_hdf5(path):
        raise RunFileError(f"{path}: not an HDF5 file")
    try:
        f = h5py.File(path, "r", swmr=True)
    except OSError as exc:
        raise RunFileError(f"{path}: cannot be opened as a run file ({exc})") from exc
    missing = [name for name in REQUIRED if name not in f]
    if missing:
        f.close()
        raise RunFileError(f"{path}: not a run file: missing {', '.join(missing)}")
    return f


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


def summarize(path: str | Path) -> RunSummary:
    with open_run(path) as f:
        n = f[S.FRAMES].shape[0]
        rows = [f[name].shape[0] for name in (S.WRENCH, S.T_FRAME)]
        n = min([n, *rows])
        w = f[S.WRENCH][:n] if n else np.zeros((0, 6))
        t = f[S.T_FRAME][:n]
        a = f.attrs
        return RunSummary(
            path=str(path), frames=n, frames_planned=int(a.get(S.ATTR_FRAMES_PLANNED, n)),
            status=f[S.STATUS][()].decode(), reason=f[S.STATUS_REASON][()].decode() if S.STATUS_REASON in f else "",
            object_name=str(a.get(S.ATTR_OBJECT, "?")), sensor_kind=str(a.get(S.ATTR_SENSOR_KIND, "?")),
            protocol=str(a.get(S.ATTR_PROTOCOL_NAME, "?")), frame_shape=tuple(f[S.FRAMES].shape[1:]),
            duration_s=float(t[-1] - t[0]) if n > 1 else 0.0,
            wrench_min=w.min(axis=0) if n else np.full(6, np.nan), wrench_max=w.max(axis=0) if n else np.full(6, np.nan),
            mm_per_px=float(a.get(S.ATTR_MM_PER_PX, np.nan)),
        )


def validate(path: str | Path, *, max_skew_s: float = 0.1, sample_frames: int = 64) -> list[str]:
    """Findings (empty when the run is sound). Frames are checked on a sample of them."""
    findings: list[str] = []
    with open_run(path) as f:
        n = f[S.FRAMES].shape[0]
        for name in (S.WRENCH, S.POSE_COMMANDED, S.POSE_MEASURED, S.T_FRAME, S.WRENCH_SKEW, S.CAPTURE_INDEX):
            if f[name].shape[0] < n:
                findings.append(f"{name}: {f[name].shape[0]} rows for {n} frames")
        shapes = {S.WRENCH: (6,), S.POSE_COMMANDED: (4,), S.POSE_MEASURED: (4,)}
        for name, shape in shapes.items():
            if f[name].shape[1:] != shape:
                findings.append(f"{name}: shape {f[name].shape[1:]} per row, expected {shape}")
        if f[S.FRAMES].dtype != np.uint8 or f[S.FRAMES].ndim != 4 or f[S.FRAMES].shape[-1] != 3:
            findings.append(f"frames: {f[S.FRAMES].dtype} {f[S.FRAMES].shape}, expected uint8 (N, H, W, 3)")
        if "units" not in f[S.WRENCH].attrs or "N·mm" not in str(f[S.WRENCH].attrs["units"]):
            findings.append("wrench: units attribute missing or not N and N·mm")
        status = f[S.STATUS][()].decode()
        if status != "complete":
            findings.append(f"status is {status!r}, not complete ({f[S.STATUS_REASON][()].decode() or 'no reason'})")
        if n == 0:
            findings.append("no frames")
            return findings
        for name in (S.WRENCH, S.POSE_COMMANDED, S.POSE_MEASURED, S.T_FRAME):
            bad = ~np.isfinite(f[name][:n])
            if bad.any():
                rows = np.nonzero(bad.reshape(n, -1).any(axis=1))[0]
                findings.append(f"{name}: NaN/inf in {len(rows)} rows (first at frame {rows[0]})")
        t = f[S.T_FRAME][:n]
        if np.any(np.diff(t) <= 0):
            findings.append(f"t_frame_s: not increasing at frame {int(np.argmax(np.diff(t) <= 0)) + 1}")
        idx = f[S.CAPTURE_INDEX][:n]
        if np.any(np.diff(idx) != 1):
            findings.append(f"capture_index: gap or duplicate at frame {int(np.argmax(np.diff(idx) != 1)) + 1}")
        skew = f[S.WRENCH_SKEW][:n]
        if np.any(skew > max_skew_s):
            findings.append(f"wrench_skew_s: {int((skew > max_skew_s).sum())} frames beyond {max_skew_s} s "
                            f"(max {skew.max():.3f} s)")
        frames = f[S.FRAMES]
        for i in np.unique(np.linspace(0, n - 1, min(n, sample_frames)).astype(int)):
            img = frames[i]
            if img.max() < 8:
                findings.append(f"frames[{i}]: all black")
            elif (img >= 250).mean() > 0.5:
                findings.append(f"frames[{i}]: saturated ({(img >= 250).mean():.0%} of pixels)")
    return findings
