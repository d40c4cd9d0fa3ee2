"""The run browser's reads: which run files the page may open, a run's series, one frame,
its marker flow, and the runs in progress (their sidecars and newest frames).

Every request opens the file anew through the verified reader (acquisition/run_reader.py's
``RunReader``: SWMR with bounded retries, the schema, the attribute checksum, every row and the
images checked at open, each frame's checksum as it is read), so a damaged file, or any other
``*.h5`` in a listed folder, is a ``RunFileError`` naming the file, the dataset and the frame
(the server answers it as a JSON error the page shows), never data read unchecked. A run that is
still being written shows the frames committed so far and grows on the next poll: the reader
counts a frame once its image is there (its row is written before it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader
from acquisition.writer_lock import RunFileError
from cli.console.run_progress import BadProgress, read_progress, sidecar_path
from common.errors import ToolError
from common.sensors import has_markers

IMAGES = {"frame": S.FRAMES, "reference": S.REFERENCE_FRAME, "object": S.OBJECT_IMAGE}


class UnknownRun(ToolError):
    """A name the page asked for that is not one of the listed run files."""


def refusal(exc: Exception) -> tuple[dict, int]:
    """The page's JSON error for a read that failed, with its HTTP status: 422 for a run file the
    verified reader refuses (damaged, malformed, not a run file), 404 for a name, kind or frame the
    page asked for that is not there."""
    return {"error": str(exc)}, 422 if isinstance(exc, RunFileError) else 404


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


def run_series(path: Path) -> dict:
    """The page's view of a run: header facts, and per committed frame its time (s, from the
    first frame), wrench (N, N·mm), measured pose (mm, deg) and phase; the phase names come
    from the file's own ``phases`` attribute. RunFileError when the file is not sound."""
    with RunReader.open(path) as run:
        n = run.n
        t = np.asarray(run.rows[S.T_FRAME], dtype=np.float64)
        return {
            "name": path.name,
            "frames": int(n),
            "frames_planned": int(run.number(S.ATTR_FRAMES_PLANNED)),
            "status": run.status,
            "reason": run.reason,
            "protocol": run.text(S.ATTR_PROTOCOL_NAME),
            "object": run.text(S.ATTR_OBJECT),
            "sensor": run.text(S.ATTR_SENSOR_KIND),
            "capture_hz": run.number(S.ATTR_CAPTURE_HZ),
            "phases": list(run.phases),
            "t_s": (t - t[0]).tolist() if n else [],
            "wrench": np.asarray(run.rows[S.WRENCH], dtype=np.float64).tolist(),
            "pose": np.asarray(run.rows[S.POSE_MEASURED], dtype=np.float64).tolist(),
            "phase_index": np.asarray(run.rows[S.PHASE_INDEX]).astype(int).tolist(),
            "has": {kind: kind == "frame" or dataset in run.images for kind, dataset in IMAGES.items()},
        }


def _frame(run: RunReader, index: int) -> np.ndarray:
    """Frame ``index`` of ``run``, its checksum verified (RunFileError naming the frame when damaged)."""
    if not 0 <= index < run.n:
        raise UnknownRun(f"{run.path.name} has frames 0..{run.n - 1}, not {index}")
    return run.frame(index)


def run_image(path: Path, kind: str, index: int = 0) -> np.ndarray:
    """One image of a run (BGR uint8): frame ``index``, the reference frame or the object image."""
    dataset = IMAGES.get(kind)
    if dataset is None:
        raise UnknownRun(f"no image kind {kind!r} (one of {', '.join(IMAGES)})")
    with RunReader.open(path) as run:
        if kind == "frame":
            return _frame(run, index)
        return run.image(dataset)


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
            except (OSError, ToolError, KeyError, ValueError, RuntimeError) as exc:
                # RuntimeError: h5py's HDF5 errors; seen while this process writes the same file (a page-started
                # protocol) and the poll's reader closes under load: one poll's pair is missing, not the endpoint
                entry["file_error"] = f"{path.name}: {exc}"
            out.append(entry)
        return out


def latest_pair(path: Path) -> dict:
    """The newest committed frame's index, wrench and measured pose, and the file's status."""
    with RunReader.open(path) as run:
        n = run.n
        return {
            "committed": int(n),
            "frames_planned": int(run.number(S.ATTR_FRAMES_PLANNED)),
            "file_status": run.status,
            "file_reason": run.reason,
            "latest_wrench": np.asarray(run.rows[S.WRENCH][n - 1], dtype=np.float64).tolist() if n else None,
            "latest_pose": np.asarray(run.rows[S.POSE_MEASURED][n - 1], dtype=np.float64).tolist() if n else None,
            "sensor": run.text(S.ATTR_SENSOR_KIND),
        }


def run_flow(path: Path, index: int) -> dict:
    """Marker flow of frame ``index`` against the run's reference frame (marker sensors):
    {"index", "markers" (found in the reference), "scale", "vectors": [[x, y, dx, dy], ...] px}."""
    from cli.console.flow import ARROW_SCALE
    from sensor_sim.markers import displacements, find_markers

    with RunReader.open(path) as run:
        sensor = run.text(S.ATTR_SENSOR_KIND)
        if not has_markers(sensor):
            raise UnknownRun(f"{path.name}: sensor {sensor or '?'} has no markers to follow")
        reference = run.image(S.REFERENCE_FRAME)
        frame = _frame(run, index)
    start = find_markers(reference)
    d = displacements(start, frame)
    return {"index": index, "markers": len(start), "scale": ARROW_SCALE, "vectors": np.round(d, 2).tolist()}
