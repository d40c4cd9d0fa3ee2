"""How a split's parts are sized and checked: frames or runs allocated to the ratio's parts, runs named
for a part, and the check that whole runs (or objects) honour the ratio asked (dataset/split.py)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dataset.split_manifest import SplitError

HONOUR_TOLERANCE = 0.2  # by run or object: each part's share of the runs this close to the ratio's, or refused


def allocate(n: int, ratios: tuple[float, ...], what: str = "frame") -> list[int]:
    """Sizes summing to n, closest to the ratios (largest remainders), every part at least 1."""
    if n < len(ratios):
        raise SplitError(
            f"{n} {what}(s) cannot fill {len(ratios)} parts (each needs at least one {what}); "
            + ("collect more frames" if what == "frame" else "add runs or split by frame")
        )
    exact = [r * n for r in ratios]
    sizes = [int(x) for x in exact]
    for i in sorted(range(len(ratios)), key=lambda i: exact[i] - sizes[i], reverse=True)[: n - sum(sizes)]:
        sizes[i] += 1
    sizes = [max(1, size) for size in sizes]  # a tiny part still gets one, taken from the largest
    while sum(sizes) > n:
        sizes[sizes.index(max(sizes))] -= 1
    return sizes


def named_runs(paths: Sequence[str | Path], named: Sequence[str | Path], option: str) -> set[int]:
    """The indices in ``paths`` of the runs ``named``: as given, the same file, or the file name (with or
    without .h5) of exactly one of them; SplitError for one that is none of these or names several."""
    resolved = [Path(p).resolve() for p in paths]
    out = set()
    for name in named:
        target = Path(name).resolve()
        if target in resolved:
            out.add(resolved.index(target))
            continue
        by_name = [i for i, p in enumerate(resolved) if str(name) in (p.name, p.stem)]
        if len(by_name) > 1:
            raise SplitError(
                f"{option} {name}: names {len(by_name)} of the runs given to split "
                f"({', '.join(str(paths[i]) for i in by_name)}); give its path"
            )
        if not by_name:
            raise SplitError(f"{option} {name}: not one of the runs given to split ({', '.join(map(str, paths))})")
        out.add(by_name[0])
    return out


def check_honoured(parts, names, ratios, ratios_text: str, by: str, groups: list[int], named_test: bool) -> None:
    """Whole runs (or objects) can only give some ratios: ``groups`` holds how many went to each part,
    SplitError, saying what they give, when a part's share of them is more than HONOUR_TOLERANCE away
    from the ratio's (8:2 of two runs is 1:1). The frames' shares are said too (runs differ in size)."""
    total = sum(groups)
    got = [g / total for g in groups] if total else list(ratios)
    if all(abs(g - r) <= HONOUR_TOLERANCE for g, r in zip(got, ratios)):
        return
    frames = sum(len(parts[name]) for name in names) or 1
    given = ":".join(str(g) for g in groups)
    asked = ":".join(f"{100 * r:g}" for r in ratios)
    raise SplitError(
        f"{ratios_text} by {by}: {total} {by}(s) can only be split {given} ("
        + ", ".join(f"{name} {len(parts[name])} frames, {100 * len(parts[name]) / frames:.0f} %" for name in names)
        + f"), not {asked}; "
        + ("" if named_test else "name the runs for the test part (--test-runs RUN,...), ")
        + "split --by frame, or add runs"
    )


def parts_of_run(parts: dict[str, np.ndarray], run: int) -> dict[str, int]:
    """{part: frames} of run ``run`` (the parts holding any of its frames)."""
    return {name: int((part[:, 0] == run).sum()) for name, part in parts.items() if (part[:, 0] == run).any()}
