"""Deterministic splits of run files: by frame, by run or by object, with held-out objects.

A split directory holds ``split.json`` (the runs, the ratios, the seed, the objects of
each part, the wrench statistics of the training part) and one ``NAME.npy`` per part:
(n, 2) int32 rows of (run index, frame index). Training and evaluation read exactly
those frames.

``hold_out`` names objects whose every frame goes to one more part, ``test_object``;
the other objects' frames are split by the ratio as usual. One split then measures
both: ``test`` (unseen frames of the training objects) and ``test_object`` (objects
never seen in training).

``hold_out_top`` (``Fz:5``) sends the N frames with the largest signed value of one wrench
component to one more part, ``test_force``, before the rest is split: the model is then tested
on loads beyond any it trained on. The sign is the one recorded: a press reads positive Fz in
this project (docs/first-day.md, docs/simulator.md), so ``Fz:N`` holds out the N hardest presses.
Ties are broken by file order (run, then frame); a tie across the cut is warned about.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acquisition import schema as S
from acquisition.run_identity import identity_of
from common.errors import ConfigError
from common.table import finite_number
from common.wording import status_text
from dataset.runs import RunSummary, open_run, summary_of
from dataset.split_manifest import MANIFEST, SplitError, check_unchanged, load_split
from dataset.split_parts import allocate, check_honoured, named_runs, parts_of_run

__all__ = [
    "MANIFEST",
    "SplitError",
    "check_unchanged",
    "load_split",
    "make_split",
    "parse_hold_out_top",
    "parse_ratios",
]

PART_NAMES = {2: ("train", "test"), 3: ("train", "val", "test")}
HELD_OUT_PART = "test_object"  # every frame of the held-out objects
RUN_PART = "test_run"  # every frame of the runs named --hold-out-runs
FORCE_PART = "test_force"  # the frames with the largest values of one wrench component (--hold-out-top)
WRENCH_COMPONENTS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")  # the wrench columns, in order (acquisition/schema.py)
WRENCH_UNITS = ("N", "N", "N", "N·mm", "N·mm", "N·mm")
TEST_PARTS = ("test", HELD_OUT_PART, RUN_PART, FORCE_PART)  # the parts evaluation reports on, when present
PERCENTILES = (2, 50, 98)  # of the training wrench, per component: the range a force sweep covers


def parse_ratios(text: str) -> tuple[float, ...]:
    """'8:2' → (0.8, 0.2); '7:1:2' → (0.7, 0.1, 0.2). Every part a finite number > 0
    (a zero part is an empty split); SplitError names the ratio and the part."""
    pieces = text.split(":")
    if len(pieces) not in PART_NAMES:
        raise SplitError(
            f"split ratio {text!r}: expected two or three parts (train:test or train:val:test) such as 8:2 or 7:1:2"
        )
    parts = []
    for name, piece in zip(PART_NAMES[len(pieces)], pieces):
        try:
            value = float(piece)
        except ValueError:
            raise SplitError(
                f"split ratio {text!r}: the {name} part {piece!r} is not a number; expected numbers "
                "joined by ':' such as 8:2 or 7:1:2"
            ) from None
        try:
            parts.append(finite_number(f"split ratio {text!r}", name, value, positive=True))
        except ConfigError as exc:
            raise SplitError(str(exc)) from None
    largest = max(parts)  # scaled first: 1e308:1e308 must not sum to inf
    parts = [p / largest for p in parts]
    total = sum(parts)
    return tuple(p / total for p in parts)


def parse_hold_out_top(text: str) -> tuple[str, int]:
    """'Fz:5' → ('Fz', 5): a wrench component (any case) and a positive whole number of frames;
    SplitError naming --hold-out-top and the value otherwise."""
    name, colon, count = str(text).strip().partition(":")
    known = {c.lower(): c for c in WRENCH_COMPONENTS}
    example = "expected COMPONENT:N such as Fz:5 (COMPONENT one of " + ", ".join(WRENCH_COMPONENTS) + ")"
    if not colon:
        raise SplitError(f"--hold-out-top {text!r}: {example}")
    component = known.get(name.strip().lower())
    if component is None:
        raise SplitError(f"--hold-out-top {text!r}: unknown wrench component {name.strip()!r}; {example}")
    try:
        n = int(count.strip())
    except ValueError:
        raise SplitError(f"--hold-out-top {text!r}: N {count.strip()!r} is not a whole number; {example}") from None
    if n < 1:
        raise SplitError(f"--hold-out-top {text!r}: N must be at least 1, got {n}")
    return component, n


def _hold_out_top(
    top: tuple[str, int], rows: np.ndarray, wrench: list[np.ndarray], paths: list[str], n_parts: int, warn
) -> tuple[np.ndarray, np.ndarray, dict]:
    """(held rows, kept rows, split.json's record): the N rows with the largest signed value of the
    component, ties broken by (run, frame) order. SplitError when N leaves nothing to split or a
    value is not finite."""
    component, n = top
    column = WRENCH_COMPONENTS.index(component)
    flag = f"--hold-out-top {component}:{n}"
    if n >= len(rows):
        raise SplitError(
            f"{flag}: N must be less than the {len(rows)} frame(s) there are to split; the rest must still "
            "fill the ratio's parts"
        )
    if len(rows) - n < n_parts:
        raise SplitError(
            f"{flag}: leaves {len(rows) - n} of the {len(rows)} frame(s), too few for the ratio's {n_parts} "
            f"parts (each needs at least one frame); hold out at most {len(rows) - n_parts}"
        )
    values = np.array([wrench[int(r)][int(f), column] for r, f in rows], dtype=np.float64)
    bad = ~np.isfinite(values)
    if bad.any():
        i = int(np.argmax(bad))
        run, frame = rows[i]
        raise SplitError(
            f"{flag}: {paths[int(run)]} frame {int(frame)} has {component} = {values[i]}, not a finite number; "
            "fix or drop that run first"
        )
    order = np.argsort(-values, kind="stable")  # rows come in (run, frame) order: ties keep it
    chosen = np.zeros(len(rows), bool)
    chosen[order[:n]] = True
    held, kept = rows[chosen], rows[~chosen]
    smallest_held, largest_kept = float(values[order[n - 1]]), float(values[order[n]])
    unit = WRENCH_UNITS[column]
    if smallest_held == largest_kept:
        warn(
            f"warning: {flag}: {component} = {smallest_held:g} {unit} at the cut is shared by frames on both "
            "sides; the earlier frames (by run, then frame) were held out"
        )
    record = {
        "part": FORCE_PART,
        "component": component,
        "column": column,
        "frames": n,
        "unit": unit,
        "smallest_held_out": smallest_held,
        "largest_held_out": float(values[order[0]]),
        "largest_kept": largest_kept,
        "order": "largest signed value first (a press reads positive Fz); ties by run, then frame",
    }
    return held, kept, record


@dataclass
class Split:
    directory: Path
    runs: list[str]
    parts: dict[str, np.ndarray]
    wrench_mean: np.ndarray
    wrench_std: np.ndarray
    held_out_top: dict | None = None  # split.json's record of --hold-out-top, when used
    where: list[dict[str, int]] | None = None  # per run: {part: frames}, as split.json records it


def make_split(
    paths: Sequence[str | Path],
    ratios_text: str,
    out: str | Path,
    *,
    seed: int = 0,
    by: str = "frame",
    allow_incomplete: bool = False,
    hold_out: Sequence[str] = (),
    hold_out_top: str | None = None,
    test_runs: Sequence[str | Path] = (),
    hold_out_runs: Sequence[str | Path] = (),
    warn=print,
) -> Split:
    """``hold_out``: object names whose frames all go to the ``test_object`` part; ``hold_out_top``
    (``Fz:5``): the frames with the largest values of a wrench component go to ``test_force`` (see
    the module docstring). ``test_runs``: runs (of ``paths``) whose frames are the ``test`` part, the
    others split by the ratio's other parts; ``hold_out_runs``: runs whose frames form ``test_run``."""
    if by not in ("frame", "run", "object"):
        raise SplitError(f"--by must be frame, run or object, got {by!r}")
    named_test = named_runs(paths, test_runs, "--test-runs")
    named_out = named_runs(paths, hold_out_runs, "--hold-out-runs")
    if named_test & named_out:
        raise SplitError("a run cannot be named both --test-runs and --hold-out-runs")
    if (named_test or named_out) and by == "object":
        raise SplitError("--test-runs and --hold-out-runs name runs: split the others --by frame or --by run")
    if len(named_test | named_out) >= len(paths):
        raise SplitError("every run is named for a test part: keep at least one to train on")
    held = sorted({name.strip() for name in hold_out if name.strip()})
    if held and by == "object":
        raise SplitError(
            f"--hold-out {','.join(held)} with --by object: --hold-out names the test objects itself; split the "
            "other objects' frames --by frame (default) or --by run"
        )
    ratios = parse_ratios(ratios_text)
    top = parse_hold_out_top(hold_out_top) if hold_out_top is not None else None
    names = PART_NAMES[len(ratios)]
    if named_test:  # the test part is the named runs: the others go to the ratio's other parts
        names, ratios = names[:-1], tuple(r / sum(ratios[:-1]) for r in ratios[:-1])
    verified = [_verified(p) for p in paths]
    summaries = [v.summary for v in verified]
    shapes = {s.frame_shape for s in summaries}
    if len(shapes) > 1:
        detail = ", ".join(f"{s.path}: {s.frame_shape}" for s in summaries)
        raise SplitError(f"frame sizes differ across runs ({detail}); resize them to one size first")
    for s in summaries:
        if s.status != "complete":
            message = (
                f"{s.path}: run is {status_text(s.status, s.reason or 'no reason recorded')}, "
                f"{s.frames}/{s.frames_planned} frames"
            )
            if not allow_incomplete:
                raise SplitError(message + "; pass --allow-incomplete to use its frames anyway")
            warn(f"warning: {message}; using its frames (--allow-incomplete)")
    rows = np.concatenate(
        [np.stack([np.full(s.frames, i), np.arange(s.frames)], axis=1) for i, s in enumerate(summaries)]
    ).astype(np.int32)
    held_rows = np.zeros((0, 2), np.int32)
    if held:
        present = sorted({s.object_name for s in summaries})
        unknown = [name for name in held if name not in present]
        if unknown:
            raise SplitError(
                f"--hold-out {','.join(unknown)}: no run of that object; the runs hold {', '.join(present)}"
            )
        if set(held) == set(present):
            raise SplitError(f"--hold-out {','.join(held)}: that is every object; keep at least one to train on")
        is_held = np.array([s.object_name in held for s in summaries])
        held_rows, rows = rows[is_held[rows[:, 0]]], rows[~is_held[rows[:, 0]]]
    named_rows: dict[str, np.ndarray] = {}
    for part, named in (("test", named_test), (RUN_PART, named_out)):
        if named:
            is_named = np.array([i in named for i in range(len(summaries))])
            named_rows[part], rows = rows[is_named[rows[:, 0]]], rows[~is_named[rows[:, 0]]]
    force_rows, force_record = None, None
    if top is not None:
        force_rows, rows, force_record = _hold_out_top(
            top, rows, [v.wrench for v in verified], [s.path for s in summaries], len(ratios), warn=warn
        )
    rng = np.random.default_rng(seed)
    if len(names) == 1:  # --test-runs with train:test: every other run trains
        parts = {names[0]: rows}
    elif by == "frame":
        sizes = allocate(len(rows), ratios)
        order = rng.permutation(len(rows))
        cuts = np.cumsum(sizes)[:-1]
        chosen = (rows[idx] for idx in np.split(order, cuts))
        parts = {name: part[np.lexsort((part[:, 1], part[:, 0]))] for name, part in zip(names, chosen)}
    else:
        keys = [s.path if by == "run" else s.object_name for s in summaries]
        left = set(np.unique(rows[:, 0]).tolist())  # runs --hold-out-top left frames of
        groups = sorted(
            {
                k
                for i, (k, s) in enumerate(zip(keys, summaries))
                if s.object_name not in held and i in left  # not held out, named or taken by --hold-out-top
            }
        )
        sizes = allocate(len(groups), ratios, what=by)
        shuffled = [groups[i] for i in rng.permutation(len(groups))]
        assignment, start = {}, 0
        for name, size in zip(names, sizes):
            for g in shuffled[start : start + size]:
                assignment[g] = name
            start += size
        run_part = np.array([names.index(assignment[k]) if k in assignment else -1 for k in keys])
        parts = {name: rows[run_part[rows[:, 0]] == j] for j, name in enumerate(names)}
        check_honoured(parts, names, ratios, ratios_text, by, list(sizes), bool(named_test))
    parts.update(named_rows)
    if held:
        parts[HELD_OUT_PART] = held_rows
    if force_rows is not None:
        parts[FORCE_PART] = force_rows
    train = parts["train"]
    wrench = np.concatenate([v.wrench[train[train[:, 0] == i][:, 1]] for i, v in enumerate(verified)])
    mean = wrench.mean(axis=0) if len(wrench) else np.zeros(6)
    std = wrench.std(axis=0) if len(wrench) else np.ones(6)
    std = np.where(std > 1e-9, std, 1.0)
    pct = np.percentile(wrench, PERCENTILES, axis=0) if len(wrench) else np.zeros((len(PERCENTILES), 6))
    objects = {
        name: sorted({summaries[int(r)].object_name for r in np.unique(part[:, 0])}) for name, part in parts.items()
    }
    manifest = {
        "ratios": ratios_text,
        "by": by,
        "seed": seed,
        "runs": [
            {
                "path": str(Path(s.path).resolve()),
                "frames": s.frames,
                "object": s.object_name,
                "sensor": s.sensor_kind,
                "status": s.status,
                "mm_per_px": s.mm_per_px,
                "frame_shape": list(s.frame_shape),
                "sensor_profile": s.sensor_profile,
                "identity": v.identity,
                "parts": parts_of_run(parts, i),  # where its frames went: {part: frames}
            }
            for i, (s, v) in enumerate(zip(summaries, verified))
        ],
        "test_runs": sorted(str(Path(summaries[i].path).resolve()) for i in named_test),
        "hold_out_runs": sorted(str(Path(summaries[i].path).resolve()) for i in named_out),
        "parts": {name: int(len(part)) for name, part in parts.items()},
        "held_out_objects": held,
        "objects": objects,
        "wrench_mean": mean.tolist(),
        "wrench_std": std.tolist(),
        "wrench_percentiles": {f"p{q}": row.tolist() for q, row in zip(PERCENTILES, pct)},
        "wrench_stats_from": "train",
    }
    if force_record is not None:
        manifest["held_out_top"] = force_record
    out = Path(out)
    _write(out, parts, manifest)
    where = [parts_of_run(parts, i) for i in range(len(summaries))]
    return Split(out, [s.path for s in summaries], parts, mean, std, force_record, where)


@dataclass(frozen=True)
class Verified:
    """A run file as the split read it: verified whole, its summary, wrench rows and identity."""

    summary: RunSummary
    wrench: np.ndarray
    identity: dict


def _verified(path: str | Path) -> Verified:
    """Open and verify the whole run (schema, rows, every frame's checksum: acquisition/run_reader.py)
    and record its identity, so that training reads only files this verification still holds for."""
    with open_run(path) as run:
        run.verify_frames()
        return Verified(summary_of(run), run.rows[S.WRENCH], identity_of(Path(path), run.f))


def _write(out: Path, parts: dict[str, np.ndarray], manifest: dict) -> None:
    """The part files and split.json into ``out`` (created), split.json last; SplitError naming the
    path when it cannot be written (a read-only folder, a full disk): nothing is half-written."""
    written: list[Path] = []
    try:
        out.mkdir(parents=True, exist_ok=True)
        for name, part in parts.items():
            target = out / f"{name}.npy"
            tmp = out / f".{name}.npy.{os.getpid()}.tmp"
            written.append(tmp)
            with open(tmp, "wb") as fh:
                np.save(fh, part)
            os.replace(tmp, target)
        tmp = out / f".{MANIFEST}.{os.getpid()}.tmp"
        written.append(tmp)
        tmp.write_text(json.dumps(manifest, indent=2) + "\n")
        os.replace(tmp, out / MANIFEST)
    except OSError as exc:
        for p in written:
            p.unlink(missing_ok=True)
        where = exc.filename or out
        raise SplitError(f"--out {out}: cannot write the split ({where}: {exc.strerror or exc})") from None
