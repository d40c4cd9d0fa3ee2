"""A split directory read back: ``split.json`` and the part files checked before anything uses them.

``load_split`` checks the manifest key by key (each error names ``split.json``, the key and what was
expected) and each part's index file (rows of (run, frame) inside the runs the manifest lists).
``check_unchanged`` compares every run file with the identity the split recorded
(acquisition/run_identity.py): ``train``, ``evaluate`` and ``generate --split`` read no frame of a
file that changed since the split verified it. It also reads every value ``split.json`` says about a
run (frames, object, sensor, status, mm per pixel, frame shape, sensor profile) back from the run
file through the verified reader and refuses a split whose ``split.json`` says otherwise: those
values place the condition and pick the physics render, and nothing ties a hand-edited ``split.json``
to the files it lists.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from acquisition import schema as S
from acquisition.run_identity import KEYS as IDENTITY_KEYS
from acquisition.run_identity import changed_since
from acquisition.run_reader import RunReader
from common.errors import ToolError

MANIFEST = "split.json"


class SplitError(ToolError):
    pass


def _whole(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _check_run(where: str, run) -> None:
    if not isinstance(run, dict):
        raise SplitError(f"{where}: expected an object describing a run file, got {run!r}")
    expected = {
        "path": (lambda v: isinstance(v, str) and v, "the run file's path"),
        "frames": (lambda v: _whole(v) and v >= 0, "a whole number of frames"),
        "object": (lambda v: isinstance(v, str), "text"),
        "sensor": (lambda v: isinstance(v, str), "text"),
        "mm_per_px": (lambda v: _number(v) and v > 0, "a positive number"),
        "frame_shape": (
            lambda v: isinstance(v, list) and len(v) == 3 and all(_whole(x) and x > 0 for x in v),
            "[H, W, C]",
        ),
        "sensor_profile": (lambda v: isinstance(v, str), 'the recorded profile\'s text ("": none)'),
    }
    for key, (ok, what) in expected.items():
        if key not in run:
            raise SplitError(
                f"{where}.{key}: missing (a split made by an older version: make it again with `dataset split`)"
            )
        if not ok(run[key]):
            raise SplitError(f"{where}.{key}: expected {what}, got {run[key]!r}")
    ident = run.get("identity")
    if ident is None:
        raise SplitError(
            f"{where}.identity: missing: this split predates recorded file identities, so nothing says its run "
            "files are the ones it verified; make it again with `dataset split`"
        )
    if not (isinstance(ident, dict) and all(k in ident for k in IDENTITY_KEYS)):
        raise SplitError(f"{where}.identity: expected {{{', '.join(IDENTITY_KEYS)}}}, got {ident!r}")
    if not (_whole(ident["size"]) and _whole(ident["mtime_ns"]) and isinstance(ident["sha256"], str)):
        raise SplitError(f"{where}.identity: expected whole numbers size, mtime_ns and text sha256, got {ident!r}")


def _check_manifest(path: Path, manifest) -> None:
    if not isinstance(manifest, dict):
        raise SplitError(f"{path}: expected a JSON object, got {type(manifest).__name__}")
    runs = manifest.get("runs")
    if not isinstance(runs, list) or not runs:
        raise SplitError(f"{path}: [runs] expected a list of run files, got {runs!r}")
    for i, run in enumerate(runs):
        _check_run(f"{path}: [runs][{i}]", run)
    parts = manifest.get("parts")
    if not isinstance(parts, dict) or not parts or not all(_whole(v) and v >= 0 for v in parts.values()):
        raise SplitError(f"{path}: [parts] expected {{part name: frame count}}, got {parts!r}")
    bad = [name for name in parts if not (isinstance(name, str) and name.isidentifier())]
    if bad:
        raise SplitError(f"{path}: [parts] part names must be plain words (train, test, ...), got {bad!r}")
    for key in ("wrench_mean", "wrench_std"):
        vec = manifest.get(key)
        if not (isinstance(vec, list) and len(vec) == 6 and all(_number(v) for v in vec)):
            raise SplitError(f"{path}: [{key}] expected six finite numbers, got {vec!r}")
    if not all(v > 0 for v in manifest["wrench_std"]):
        raise SplitError(f"{path}: [wrench_std] expected positive numbers, got {manifest['wrench_std']!r}")
    if "held_out_top" in manifest:
        _check_held_out_top(path, manifest["held_out_top"], parts)


def _check_held_out_top(path: Path, top, parts: dict) -> None:
    """``held_out_top`` (dataset split --hold-out-top): its component, frame count and values, and a
    ``test_force`` part of that many frames."""
    ok = (
        isinstance(top, dict)
        and top.get("component") in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
        and _whole(top.get("frames"))
        and top["frames"] >= 1
        and isinstance(top.get("unit"), str)
        and all(_number(top.get(k)) for k in ("smallest_held_out", "largest_held_out", "largest_kept"))
        and top.get("part") == "test_force"
    )
    if not ok:
        raise SplitError(
            f"{path}: [held_out_top] expected {{part, component (Fx..Mz), frames >= 1, unit, smallest_held_out, "
            f"largest_held_out, largest_kept}}, got {top!r}"
        )
    if parts.get(top["part"]) != top["frames"]:
        raise SplitError(
            f"{path}: [held_out_top] says {top['frames']} frame(s) in part {top['part']!r}, [parts] says "
            f"{parts.get(top['part'])!r}"
        )


def _load_part(directory: Path, name: str, count: int, runs: list[dict]) -> np.ndarray:
    path = directory / f"{name}.npy"
    try:
        rows = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise SplitError(f"{path}: not a readable index file ({str(exc).strip().splitlines()[0]})") from None
    if rows.ndim != 2 or rows.shape[1] != 2 or rows.dtype.kind not in "iu":
        raise SplitError(f"{path}: expected (n, 2) whole-number rows of (run, frame), got {rows.dtype} {rows.shape}")
    if len(rows) != count:
        raise SplitError(f"{path}: {len(rows)} rows, {MANIFEST} says the {name} part has {count}")
    if len(rows):
        frames = np.array([r["frames"] for r in runs])
        run, frame = rows[:, 0], rows[:, 1]
        bad = (run < 0) | (run >= len(runs))
        bad |= ~bad & ((frame < 0) | (frame >= frames[np.clip(run, 0, len(runs) - 1)]))
        if bad.any():
            i = int(np.argmax(bad))
            raise SplitError(
                f"{path}: row {i} is (run {run[i]}, frame {frame[i]}), outside the {len(runs)} run(s) of {MANIFEST}"
            )
    return rows


def load_split(directory: str | Path) -> tuple[dict, dict[str, np.ndarray]]:
    """(manifest, {part: rows}) of a split directory, checked (module docstring)."""
    directory = Path(directory)
    path = directory / MANIFEST
    if not path.is_file() and (directory / "meta" / "info.json").is_file():
        raise SplitError(
            f"{directory}: a LeRobot dataset, not a split: training reads run files through a split; import it first "
            f"(dataset import {directory} --format lerobot --out RUN.h5), then `dataset split 8:2 RUN.h5 --out SPLIT`"
        )
    if not path.is_file():
        raise SplitError(f"{directory}: no {MANIFEST}; make one with `dataset split`")
    try:
        manifest = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise SplitError(f"{path}: cannot be read ({exc})") from None
    except json.JSONDecodeError as exc:
        raise SplitError(f"{path}: not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None
    _check_manifest(path, manifest)
    parts = {name: _load_part(directory, name, count, manifest["runs"]) for name, count in manifest["parts"].items()}
    return manifest, parts


def check_unchanged(manifest: dict, directory: str | Path) -> None:
    """SplitError naming the first run file that changed since the split recorded its identity, or
    the first value of ``split.json`` its run file does not say (module docstring)."""
    for i, run in enumerate(manifest["runs"]):
        change = changed_since(run["path"], run["identity"])
        if change:
            raise SplitError(
                f"{run['path']}: changed since the split {directory} verified it: {change}; make the split again "
                "with `dataset split` (it verifies the file anew)"
            )
        with RunReader.open(run["path"]) as reader:
            differs = _differs(run, reader)
        if differs:
            key, said, actual = differs
            raise SplitError(
                f"{Path(directory) / MANIFEST}: [runs][{i}].{key} is {said!r}, but the run file {run['path']} says "
                f"{actual!r}: {MANIFEST} was changed since the split was made; make the split again with "
                "`dataset split`"
            )


def _differs(run: dict, reader: RunReader) -> tuple[str, object, object] | None:
    """(key, split.json's value, the run file's) of the first value that differs; None when all agree."""
    actual = {
        "frames": reader.n,
        "object": reader.text(S.ATTR_OBJECT),
        "sensor": reader.text(S.ATTR_SENSOR_KIND),
        "status": reader.status,
        "mm_per_px": reader.number(S.ATTR_MM_PER_PX),
        "frame_shape": list(reader.frame_shape),
        "sensor_profile": reader.sensor_profile,
    }
    for key, value in actual.items():
        if key in run and run[key] != value:
            return key, run[key], value
    return None
