"""Where the force sweep (model/sweeps/force_sweep.py) sweeps: the components it sweeps and their training
ranges (the split's 2nd to 98th percentile; ``swept_ranges`` skips a component without one), each
narrowed to what a pose's own run recorded (``pose_range``), and the test poses themselves, spread
over the field and the loads (``choose_poses``; ``pose_runs`` says how many runs they come from).
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np

COMPONENTS = {"Fz": 2, "Fx": 0, "Fy": 1, "Mz": 5}  # the swept components, index into the six-axis wrench
UNITS = {"Fz": "N", "Fx": "N", "Fy": "N", "Mz": "N·mm"}


def training_range(percentiles: dict, component: str) -> tuple[float, float]:
    """The sweep range of a component: the split's 2nd and 98th percentile of the training wrench."""
    k = COMPONENTS[component]
    low, high = float(percentiles["p2"][k]), float(percentiles["p98"][k])
    if not (math.isfinite(low) and math.isfinite(high)):
        raise ValueError(f"the split's {component} percentiles are not finite: {low}, {high}")
    return low, high


def pose_range(split_range: tuple[float, float], recorded: np.ndarray, component: str, run: str) -> tuple:
    """(low, high, note): the split's training range of ``component`` within what the pose's run recorded
    (``recorded``: that component over its frames, smallest to largest); the note says when that narrows
    it (and, when nothing is left, why the pose is not swept). The run's extremes, not its percentiles:
    the split's range is already its training part's 2nd–98th percentile, and a run holding the split's
    largest loads must count as reaching it (24 presses: the run's 98th percentile, 1.75 N, fell below
    the 19 training frames', 1.76 N, and the sweep went nowhere past the maximum)."""
    low, high = split_range
    values = np.asarray(recorded, dtype=np.float64)
    values = values[np.isfinite(values)]
    if not len(values):
        return low, low, f"{run} recorded no finite {component}"
    run_low, run_high = float(values.min()), float(values.max())
    lo, hi = max(low, run_low), min(high, run_high)
    unit = UNITS[component]
    if lo <= low and hi >= high:
        return low, high, ""
    words = (
        f"the split's training range {low:+.2f} … {high:+.2f} {unit} within {run}'s own "
        f"{run_low:+.2f} … {run_high:+.2f}"
    )
    if not hi - lo > 1e-6 * max(1.0, abs(lo), abs(hi)):
        return lo, lo, f"{words}: nothing left"
    past = "" if hi >= high else "; no value past the training maximum (this run does not reach it)"
    return lo, hi, f"swept over {lo:+.2f} … {hi:+.2f} {unit}: {words}{past}"


def swept_ranges(percentiles: dict, components: Sequence[str]) -> tuple[dict[str, tuple[float, float]], dict[str, str]]:
    """(the components to sweep and their training ranges, the skipped ones and why): a component
    whose 2nd and 98th percentiles coincide has no range in the training data (an import without
    shear, a gauge that does not measure it), and a sweep of it would show nothing."""
    ranges, skipped = {}, {}
    for name in components:
        low, high = training_range(percentiles, name)
        if high - low <= 1e-6 * max(1.0, abs(low), abs(high)):
            skipped[name] = (
                f"{name}: no range in the training data (2nd to 98th percentile {low:+.2f} … {high:+.2f} "
                f"{UNITS[name]}): not swept"
            )
        else:
            ranges[name] = (low, high)
    return ranges, skipped


def choose_poses(
    rows: np.ndarray, wrench_of: Callable[[int], np.ndarray], pose_of: Callable[[int], np.ndarray], n: int, std
) -> list[tuple[int, int]]:
    """``n`` pose frames (run, frame) from a part's ``rows`` spread over the field and the loads: among
    the frames in contact (Fz between the part's 10th and 95th percentile) with little shear (|Fx|/σx +
    |Fy|/σy at most its median there), the one nearest the middle first, then each time the frame
    farthest from those chosen in (x, y, Fz), each scaled by its span over those frames; no two within
    0.5 mm and 2 % of the Fz span of each other (``pose_runs`` says how many runs they span). Poses
    next to each other in Fz, on one side of the field, made the sweep's verdict depend on the pick."""
    runs = sorted({int(r) for r in rows[:, 0]})
    if not runs:
        return []
    candidates = []  # (run, frame, x, y, Fz, shear)
    for r in runs:
        frames = rows[rows[:, 0] == r][:, 1]
        w, pose = wrench_of(r)[frames], pose_of(r)[frames]
        shear = np.abs(w[:, 0]) / std[0] + np.abs(w[:, 1]) / std[1]
        candidates += [(r, int(f), *pose[i, :2], w[i, 2], shear[i]) for i, f in enumerate(frames)]
    table = np.array([c[2:] for c in candidates], dtype=float)
    lo, hi = np.percentile(table[:, 2], [10, 95])
    contact = (table[:, 2] >= lo) & (table[:, 2] <= hi)
    if not contact.any():
        return []
    calm = contact & (table[:, 3] <= np.median(table[contact, 3]))
    keep = np.nonzero(calm if calm.any() else contact)[0]
    points = table[keep, :3]
    span = np.maximum(points.max(axis=0) - points.min(axis=0), 1e-9)
    scaled = (points - points.min(axis=0)) / span
    chosen = [int(np.argmin(np.linalg.norm(scaled - np.median(scaled, axis=0), axis=1)))]
    nearest = np.linalg.norm(scaled - scaled[chosen[0]], axis=1)
    while len(chosen) < min(n, len(keep)):
        j = int(np.argmax(nearest))
        if nearest[j] <= 0:
            break
        close = np.linalg.norm(points[j, :2] - points[chosen, :2], axis=1) < 0.5
        if (close & (np.abs(points[j, 2] - points[chosen, 2]) < 0.02 * span[2])).any():
            nearest[j] = 0.0  # a twin of a chosen pose
            continue
        chosen.append(j)
        nearest = np.minimum(nearest, np.linalg.norm(scaled - scaled[j], axis=1))
    return [(candidates[keep[i]][0], candidates[keep[i]][1]) for i in chosen]


def pose_runs(poses: Sequence[tuple[int, int]], names: dict[int, str]) -> str:
    """How many runs the poses come from, in words, naming the poses that share one."""
    runs = [r for r, _ in poses]
    distinct = sorted(set(runs))
    if len(distinct) == len(runs):
        return f"{len(poses)} poses, each from a different run"
    shared = [
        f"poses {', '.join(str(i + 1) for i, rr in enumerate(runs) if rr == r)} from {names.get(r, f'run {r}')}"
        for r in distinct
        if runs.count(r) > 1
    ]
    return f"{len(poses)} poses from {len(distinct)} run(s), so not all from different runs: " + "; ".join(shared)
