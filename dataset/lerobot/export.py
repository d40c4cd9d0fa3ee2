"""Runs (or a split) to a LeRobotDataset v3.0 folder (layout: dataset/lerobot/layout.py).

Every run is read through the verified reader (each frame's checksum as it is read) and the folder is
written under a temporary name beside ``--out``, renamed only when complete. The video of each episode
is decoded again before the rename: with the lossless codec every frame must equal the run's (its
BLAKE2b digest, kept in export.json for import); with a lossy one the mean squared error against the
run's frames is measured and reported. export.json holds the SHA-256 of every file, which import checks.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader
from acquisition.whole_run import whole_folder
from acquisition.writer_lock import RunFileError
from dataset.lerobot import layout as L
from dataset.lerobot.card import card_text
from dataset.lerobot.episodes import Episode, plan, plan_split, split_ranges
from dataset.lerobot.meta import episodes_table, info_json, run_record, tasks_table
from dataset.lerobot.parquet import write_table
from dataset.lerobot.stats import aggregate, as_json, downsampled, image_stats, numeric_stats, sample_indices
from dataset.lerobot.video import codec, read_video, write_video
from dataset.lerobot.window import WrenchWindows
from dataset.split_manifest import MANIFEST, check_unchanged, load_split


@dataclass
class ExportSummary:
    out: Path
    runs: int
    episodes: int
    frames: int
    codec: str
    splits: dict[str, str]
    bytes: int = 0
    video_bytes: int = 0
    seconds: float = 0.0
    mse: list[float] = field(default_factory=list)  # lossy codecs: per frame, against the run's frames


def frame_digest(frame_bgr: np.ndarray) -> str:
    return hashlib.blake2b(np.ascontiguousarray(frame_bgr).tobytes(), digest_size=16).hexdigest()


def _check_out(out: Path) -> None:
    if out.exists() and not (out.is_dir() and not any(out.iterdir())):
        raise RunFileError(f"--out {out}: exists; export writes a new folder: choose another --out")
    if not out.parent.is_dir():
        raise RunFileError(f"--out {out}: the folder {out.parent} does not exist; create it first")


def _fps(run: RunReader) -> int:
    hz = run.number(S.ATTR_CAPTURE_HZ)
    if not (np.isfinite(hz) and hz >= 1 and abs(hz - round(hz)) < 1e-9):
        raise RunFileError(
            f"{run.path}: capture rate {hz:g} Hz: a LeRobot dataset needs a whole number of frames per second"
        )
    return int(round(hz))


def _sources(sources: list[Path]) -> tuple[list[str], dict[str, np.ndarray] | None]:
    if len(sources) == 1 and sources[0].is_dir():
        manifest, parts = load_split(sources[0])
        check_unchanged(manifest, sources[0])
        return [run["path"] for run in manifest["runs"]], parts
    for path in sources:
        if path.is_dir():
            raise RunFileError(f"{path}: a folder without {MANIFEST}: export takes run files or one split folder")
    return [str(p) for p in sources], None


def export_lerobot(
    sources: list[Path],
    out: Path,
    *,
    codec_name: str = "lossless",
    episode: str = "run",
    say=lambda line: None,
    clock=time.monotonic,
) -> ExportSummary:
    """A LeRobot folder at ``out`` from run files or one split folder (module docstring)."""
    chosen = codec(codec_name)
    out = Path(out)
    _check_out(out)
    start = clock()
    paths, parts = _sources([Path(s) for s in sources])
    with contextlib.ExitStack() as stack:
        runs = [stack.enter_context(RunReader.open(p)) for p in paths]
        fps = _fps(runs[0])
        for run in runs[1:]:
            if _fps(run) != fps or run.frame_shape != runs[0].frame_shape:
                raise RunFileError(
                    f"{run.path}: {run.frame_shape[1]}x{run.frame_shape[0]} px at {_fps(run)} Hz, the first run's "
                    f"{runs[0].frame_shape[1]}x{runs[0].frame_shape[0]} px at {fps} Hz: a LeRobot dataset has one "
                    "camera shape and one frame rate"
                )
        levels = [np.asarray(run.rows[S.LEVEL]) for run in runs]
        episodes = plan(levels, episode) if parts is None else plan_split(levels, parts, episode, Path(sources[0]))
        summary = ExportSummary(
            out, len(runs), len(episodes), sum(len(e.frames) for e in episodes), chosen.name, split_ranges(episodes)
        )
        with whole_folder(out, "export") as tmp:
            _write(tmp, runs, episodes, fps, chosen, summary, say)
        summary.bytes = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
        summary.video_bytes = sum(p.stat().st_size for p in (out / "videos").rglob("*") if p.is_file())
    summary.seconds = clock() - start
    return summary


def _write(folder: Path, runs: list[RunReader], episodes: list[Episode], fps: int, chosen, summary, say) -> None:
    windows = WrenchWindows(runs, fps, episodes)
    features = _features(runs[0], fps, chosen, windows)
    tasks = [_task(run) for run in runs]
    task_names = list(dict.fromkeys(tasks))
    per_episode: list[dict] = []
    stats: list[dict[str, dict]] = []
    digests: list[list[str]] = []
    offset = 0
    for i, ep in enumerate(episodes):
        run = runs[ep.run]
        n = len(ep.frames)
        seen: list[np.ndarray] = []
        digest: list[str] = []

        video = folder / L.video_file(i)
        video.parent.mkdir(parents=True, exist_ok=True)
        write_video(video, _frames(run, ep, digest, seen), fps, chosen)
        _check_video(video, run, ep, digest, chosen.lossless, summary)
        columns = _columns(run, ep, i, offset, task_names.index(tasks[ep.run]), fps, windows)
        write_table(folder / L.data_file(i), columns, features)
        ep_stats = {k: numeric_stats(v) for k, v in columns.items()}
        ep_stats[L.CAMERA] = image_stats(np.stack(seen))
        stats.append(ep_stats)
        digests.append(digest)
        per_episode.append({"episode": i, "length": n, "from": offset, "task": tasks[ep.run], "stats": ep_stats})
        _condition(folder, i, run, ep)
        offset += n
        say(f"episode {i + 1}/{len(episodes)}: {n} frames of {run.path.name}" + (f" ({ep.part})" if ep.part else ""))
    for r, run in enumerate(runs):
        _run_files(folder, r, run)
    write_table(folder / L.EPISODES, *episodes_table(per_episode, fps))
    columns, described, index = tasks_table(task_names)
    write_table(folder / L.TASKS, columns, described, pandas_index=index)
    total = {k: aggregate([s[k] for s in stats]) for k in stats[0]}
    (folder / L.STATS).write_text(json.dumps(as_json(total), indent=2) + "\n")
    info = info_json(features, fps, len(episodes), offset, len(task_names), summary.splits)
    (folder / L.INFO).write_text(json.dumps(info, indent=4) + "\n")
    (folder / "README.md").write_text(card_text(runs, info, chosen, summary))
    _export_json(folder, runs, episodes, digests, chosen, summary)


def _frames(run: RunReader, ep: Episode, digest: list[str], seen: list[np.ndarray]):
    """The episode's frames as the run holds them (each checksum verified as read), noting each one's digest
    and keeping the statistics' sample (RGB, downsampled)."""
    sampled = set(sample_indices(len(ep.frames)))
    for k, j in enumerate(ep.frames):
        frame = run.frame(int(j))
        digest.append(frame_digest(frame))
        if k in sampled:
            seen.append(downsampled(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)))
        yield frame


def _features(run: RunReader, fps: int, chosen, windows: WrenchWindows) -> dict[str, dict]:
    h, w, _ = run.frame_shape
    features = {L.CAMERA: L.camera_feature(h, w, fps, {"codec": chosen.info_codec, "pix_fmt": chosen.info_pix_fmt})}
    for fl in S.PER_FRAME_FIELDS:
        features[L.feature_name(fl)] = L.field_feature(fl)
    features[L.FRAME_IN_RUN] = {"dtype": "int64", "shape": [1], "names": [L.FRAME_IN_RUN]}
    if windows.width:
        features.update(L.window_features(windows.width))
    return {**features, **L.DEFAULT_FEATURES}


def _task(run: RunReader) -> str:
    return (
        f"{run.text(S.ATTR_PROTOCOL_NAME)}: {run.text(S.ATTR_OBJECT)} pressed on a "
        f"{run.text(S.ATTR_SENSOR_KIND)} tactile sensor"
    )


def _columns(run, ep: Episode, i: int, offset: int, task: int, fps: int, windows: WrenchWindows) -> dict:
    n = len(ep.frames)
    cols: dict[str, np.ndarray] = {}
    for fl in S.PER_FRAME_FIELDS:
        if fl.path in run.f:
            values = np.asarray(run.rows[fl.path])[ep.frames]
        else:  # a file from before the field: its documented fill (acquisition/schema.py)
            values = np.full((n, *fl.shape), fl.fill)
        cols[L.feature_name(fl)] = values.astype(np.float64 if fl.dtype.startswith("f") else np.int64)
    cols[L.FRAME_IN_RUN] = ep.frames.astype(np.int64)
    cols.update(windows.columns(ep))
    cols["timestamp"] = (np.arange(n) / fps).astype(np.float32)
    cols["frame_index"] = np.arange(n, dtype=np.int64)
    cols["episode_index"] = np.full(n, i, dtype=np.int64)
    cols["index"] = offset + np.arange(n, dtype=np.int64)
    cols["task_index"] = np.full(n, task, dtype=np.int64)
    return cols


def _check_video(video: Path, run, ep: Episode, digest: list[str], lossless: bool, summary: ExportSummary) -> None:
    n = 0
    for k, frame in enumerate(read_video(video)):
        if k >= len(ep.frames):
            break
        if lossless and frame_digest(frame) != digest[k]:
            raise RunFileError(
                f"{video.name}: frame {k} decodes differently from {run.path.name} frame "
                f"{int(ep.frames[k])}; the lossless codec did not round-trip; nothing was written"
            )
        if not lossless:
            source = run.frame(int(ep.frames[k])).astype(np.float64)
            summary.mse.append(float(np.mean((frame.astype(np.float64) - source) ** 2)))
        n += 1
    if n != len(ep.frames):
        raise RunFileError(f"{video.name}: {n} frames decode, {len(ep.frames)} were written; nothing was written")


def _png(path: Path, image: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), image):
        raise OSError(f"cannot write {path}")


def _condition(folder: Path, i: int, run: RunReader, ep: Episode) -> None:
    """The contact condition of episode ``i``: the object's image (at pose 0) and what places it."""
    where = folder / L.episode_folder(i)
    _png(where / "object.png", run.image(S.OBJECT_IMAGE))
    record = run_record(run)
    condition = {k: record[k] for k in ("object", "object_geometry", "sensor", "mm_per_px", "pose_convention")}
    condition.update(
        run=ep.run,
        run_file=run.path.name,
        part=ep.part,
        frames=[int(ep.frames[0]), int(ep.frames[-1])],
        **described_rig(run.text(S.ATTR_RIG_CONFIG), run.text(S.ATTR_SENSOR_PROFILE)),
    )
    (where / "condition.json").write_text(json.dumps(condition, indent=2) + "\n")


def _toml(text: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return {}


def described_rig(rig_config: str, profile: str) -> dict:
    """The rig (its name, or the config's first line), the gauge's driver and the sensor profile (name and
    sha256) as condition.json says them; "" where the run's record does not say."""
    rig, record = _toml(rig_config), _toml(profile)
    lines = rig_config.splitlines()
    return {
        "rig": rig.get("rig", {}).get("name") or (lines[0].lstrip("# ") if lines else ""),
        "simulated": rig_config.startswith(S.RIG_CONFIG_MARK),
        "gauge": rig.get("gauge", {}).get("driver", ""),
        "camera": rig.get("camera", {}).get("driver", ""),
        "sensor_profile": {k: record.get(k, "") for k in ("name", "sha256")} if profile.strip() else None,
    }


def _run_files(folder: Path, r: int, run: RunReader) -> None:
    where = folder / L.run_folder(r)
    where.mkdir(parents=True, exist_ok=True)
    (where / "run.json").write_text(json.dumps(run_record(run), indent=2) + "\n")
    _png(where / "object.png", run.image(S.OBJECT_IMAGE))
    _png(where / "reference.png", run.image(S.REFERENCE_FRAME))
    if run.stream is not None and len(run.stream):
        np.save(where / "wrench_stream.npy", np.asarray(run.stream, dtype=np.float64))


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _export_json(folder: Path, runs, episodes: list[Episode], digests, chosen, summary: ExportSummary) -> None:
    record = {
        "format": L.FORMAT_MARK,
        "codec": chosen.name,
        "lossless": chosen.lossless,
        "runs": [{"file": run.path.name, "frames": run.n} for run in runs],
        "episodes": [
            {"run": e.run, "part": e.part, "frames": e.frames.tolist(), "frame_blake2b": d}
            for e, d in zip(episodes, digests)
        ],
        "mse_mean": float(np.mean(summary.mse)) if summary.mse else 0.0,
        "files": {name: sha256(folder / name) for name in L.relative_files(folder)},
    }
    (folder / L.EXPORT_JSON).write_text(json.dumps(record) + "\n")
