"""Which frames make each episode: one per run, one per press, or per part of a split.

A press is a depth level: the frames from one level's first frame to the next level's, the frames
before the first level (the approach) going with the first press and those after the last (the
retract) with the last. A split exports each part's frames of each run as their own episodes, parts
in the manifest's order, so that each part is one range of episodes (info.json's ``splits``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.errors import ToolError

EPISODE_KINDS = ("run", "press")


@dataclass(frozen=True)
class Episode:
    run: int  # index into the export's source runs
    frames: np.ndarray  # the frames' indices in that run, increasing
    part: str = ""  # the split's part ("": not exported from a split)


def presses(levels: np.ndarray) -> list[np.ndarray]:
    """Frame indices per press (module docstring); one group when no frame is at a level."""
    press = np.zeros(len(levels), dtype=np.int64)
    current, last = 0, None
    for i, level in enumerate(np.asarray(levels).tolist()):
        if level > 0 and level != last:
            current, last = current + (last is not None), level
        press[i] = current
    return [np.flatnonzero(press == k) for k in range(int(press.max()) + 1)] if len(press) else [press]


def plan(levels: list[np.ndarray], kind: str) -> list[Episode]:
    """Episodes of whole runs (``levels``: each run's per-frame levels)."""
    if kind not in EPISODE_KINDS:
        raise ToolError(f"--episode {kind!r}: expected one of {', '.join(EPISODE_KINDS)}")
    out = []
    for r, lv in enumerate(levels):
        groups = [np.arange(len(lv))] if kind == "run" else presses(lv)
        out += [Episode(r, g) for g in groups if len(g)]
    return out


def plan_split(levels: list[np.ndarray], parts: dict[str, np.ndarray], kind: str, where: Path) -> list[Episode]:
    """Episodes of a split's parts (``parts``: part -> (n, 2) rows of (run, frame)), each part's in a range."""
    if kind not in EPISODE_KINDS:
        raise ToolError(f"--episode {kind!r}: expected one of {', '.join(EPISODE_KINDS)}")
    out = []
    for part, rows in parts.items():
        for r, lv in enumerate(levels):
            frames = np.sort(rows[rows[:, 0] == r, 1]).astype(np.int64)
            if not len(frames):
                continue
            if kind == "run":
                out.append(Episode(r, frames, part))
                continue
            for group in presses(lv):
                inside = frames[np.isin(frames, group)]
                if len(inside):
                    out.append(Episode(r, inside, part))
    if not out:
        raise ToolError(f"{where}: the split's parts hold no frame")
    return out


def split_ranges(episodes: list[Episode]) -> dict[str, str]:
    """info.json's ``splits``: part -> "first:end" over episode indices ("train": all, when not a split)."""
    if not episodes or not episodes[0].part:
        return {"train": f"0:{len(episodes)}"}
    ranges: dict[str, list[int]] = {}
    for i, e in enumerate(episodes):
        ranges.setdefault(e.part, [i, i + 1])[1] = i + 1
    return {part: f"{a}:{b}" for part, (a, b) in ranges.items()}
