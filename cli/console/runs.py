"""The run browser's reads: which run files the page may open, a run's series, one frame,
its marker flow, and the runs in progress (their sidecars and newest frames).

Every request opens the file anew (``open_for_reading``: SWMR, bounded retries), so a run
that is still being written shows the frames committed so far and grows on the next poll.
A frame counts once its row and its image are both there (the writer commits them together,
a reader between the two flushes sees one more of one of them).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acquisition import schema as S
from acquisition.run_file import open_for_reading
from acquisition.run_layout import decode_phases
from cli.console.run_progress import BadProgress, read_progress, sidecar_path
from common.errors import ToolError
from common.sensors import has_markers

ROW_FIELDS = (S.WRENCH, S.POSE_MEASURED, S.T_FRAME, S.PHASE_INDEX)
IMAGES = {"frame": S.FRAMES, "reference": S.REFERENCE_FRAME, "object": S.OBJECT_IMAGE}


class UnknownRun(ToolError):
    """A name the page asked for that is not one of the listed run files."""


@dataclass
class RunLibrary:
    """The run files the page may read: the ``*.h5`` in ``folders`` and the ``files`` named on
    the command line. Only names from this listing are opened, never a path from the page."""

    folders: list[Path] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)

    def listing(self) -> dict[str, Path]:
        found: dict[str, Path] = {}
        for path in self.files:
            found[path.name] = path
        for folder in self.folders:
            if folder.is_dir():
                for path in sorted(folder.glob("*.h5")):
                    found.setdefault(path.name, path)
        return found

    def path(self, name: str) -> Path:
        path = self.listing().get(name)
        if path is None:
            raise UnknownRun(f"no run file named {name!r} here")
        return path


def _text(value) -> str:
    value = value[()] if hasattr(value, "shape") else value
    return value.decode() if isinstance(value, bytes) else str(value)


def run_series(path: Path) -> dict:
    """The page's view of a run: header facts, and per committed frame its time (s, from the
    first frame), wrench (N, N·mm), measured pose (mm, deg) and phase; the phase names come
    from the file's own ``phases`` attribute."""
    with open_for_reading(path) as f:
        n = min(f[S.FRAMES].shape[0], *(f[name].shape[0] for name in ROW_FIELDS))
        t = np.asarray(f[S.T_FRAME][:n], dtype=np.float64)
        return {
            "name": path.name,
            "frames": int(n),
            "frames_planned": int(f.attrs.get(S.ATTR_FRAMES_PLANNED, 0)),
            "status": _text(f[S.STATUS]) if S.STATUS in f else "?",
            "reason": _text(f[S.STATUS_REASON]) if S.STATUS_REASON in f else "",
            "protocol": _text(f.attrs.get(S.ATTR_PROTOCOL_NAME, "")),
            "object": _text(f.attrs.get(S.ATTR_OBJECT, "")),
            "sensor": _text(f.attrs.get(S.ATTR_SENSOR_KIND, "")),
            "capture_hz": float(f.attrs.get(S.ATTR_CAPTURE_HZ, 0.0)),
            "phases": list(decode_phases(f)),
            "t_s": (t - t[0]).tolist() if n else [],
            "wrench": np.asarray(f[S.WRENCH][:n], dtype=np.float64).tolist(),
            "pose": np.asarray(f[S.POSE_MEASURED][:n], dtype=np.float64).tolist(),
            "phase_index": np.asarray(f[S.PHASE_INDEX][:n]).astype(int).tolist(),
            "has": {kind: dataset in f for kind, dataset in IMAGES.items()},
        }


def run_image(path: Path, kind: str, index: int = 0) -> np.ndarray:
    """One image of a run (BGR uint8): frame ``index``, the reference frame or the object image."""
    dataset = IMAGES.get(kind)
    if dataset is None:
        raise UnknownRun(f"no image kind {kind!r} (one of {', '.join(IMAGES)})")
    with open_for_reading(path) as f:
        if dataset not in f:
            raise UnknownRun(f"{path.name} has no {dataset}")
        if kind != "frame":
            return np.asarray(f[dataset][()])
        count = f[S.FRAMES].shape[0]
        if not 0 <= index < count:
            raise UnknownRun(f"{path.name} has frames 0..{count - 1}, not {index}")
        return np.asarray(f[S.FRAMES][index])


FINISHED_SHOWN_S = 600.0  # a run seen in progress stays in the panel this long after it ended


@dataclass
class ProgressWatch:
    """Runs in progress among the library's files: their sidecars (cli/console/run_progress.py)
    and the latest committed pair of each run file. A run seen in progress whose sidecar is
    gone has ended; it is shown with its file's status for FINISHED_SHOWN_S."""

    library: RunLibrary
    seen: dict[str, float] = field(default_factory=dict)  # run name -> wall time it was last seen running

    def poll(self, wall: float) -> list[dict]:
        out = []
        for name, path in self.library.listing().items():
            side = sidecar_path(path)
            if side.exists():
                try:
                    entry = read_progress(side, lambda: wall)
                except BadProgress as exc:
                    out.append({"run": name, "error": str(exc)})
                    continue
                entry["run"] = name  # the listing's name, whatever the file says
                entry["finished"] = False
                self.seen[name] = wall
            elif name in self.seen and wall - self.seen[name] < FINISHED_SHOWN_S:
                entry = {"run": name, "finished": True}
            else:
                continue
            try:
                entry.update(latest_pair(path))
            except (OSError, ToolError, KeyError, ValueError) as exc:
                entry["file_error"] = f"{path.name}: {exc}"
            out.append(entry)
        return out


def latest_pair(path: Path) -> dict:
    """The newest committed frame's index, wrench and measured pose, and the file's status."""
    with open_for_reading(path) as f:
        n = min(f[S.FRAMES].shape[0], *(f[name].shape[0] for name in ROW_FIELDS))
        return {
            "committed": int(n),
            "frames_planned": int(f.attrs.get(S.ATTR_FRAMES_PLANNED, 0)),
            "file_status": _text(f[S.STATUS]) if S.STATUS in f else "?",
            "file_reason": _text(f[S.STATUS_REASON]) if S.STATUS_REASON in f else "",
            "latest_wrench": np.asarray(f[S.WRENCH][n - 1], dtype=np.float64).tolist() if n else None,
            "latest_pose": np.asarray(f[S.POSE_MEASURED][n - 1], dtype=np.float64).tolist() if n else None,
            "sensor": _text(f.attrs.get(S.ATTR_SENSOR_KIND, "")),
        }


def run_flow(path: Path, index: int) -> dict:
    """Marker flow of frame ``index`` against the run's reference frame (marker sensors):
    {"index", "markers" (found in the reference), "scale", "vectors": [[x, y, dx, dy], ...] px}."""
    from cli.console.flow import ARROW_SCALE
    from sensor_sim.markers import displacements, find_markers

    with open_for_reading(path) as f:
        sensor = _text(f.attrs.get(S.ATTR_SENSOR_KIND, ""))
        if not has_markers(sensor):
            raise UnknownRun(f"{path.name}: sensor {sensor or '?'} has no markers to follow")
        if S.REFERENCE_FRAME not in f:
            raise UnknownRun(f"{path.name} has no {S.REFERENCE_FRAME}")
        count = f[S.FRAMES].shape[0]
        if not 0 <= index < count:
            raise UnknownRun(f"{path.name} has frames 0..{count - 1}, not {index}")
        reference = np.asarray(f[S.REFERENCE_FRAME][()])
        frame = np.asarray(f[S.FRAMES][index])
    start = find_markers(reference)
    d = displacements(start, frame)
    return {"index": index, "markers": len(start), "scale": ARROW_SCALE, "vectors": np.round(d, 2).tolist()}
