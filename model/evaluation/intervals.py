"""Uncertainty: bootstrap intervals over frames, and the spread of a result over training seeds.

A metric averaged over test frames is a sample mean; ``bootstrap_interval`` resamples the frames
with replacement (a fixed seed: the same interval every time) and gives the 2.5th and 97.5th
percentiles of the resampled means. Across models trained with different seeds, ``seed_spread``
gives the mean, the standard deviation and the range; ``differs`` says whether two settings'
difference exceeds both their spreads (the rule defaults are chosen by).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

RESAMPLES = 2000
LEVEL = 0.95


def bootstrap_interval(
    values: Sequence[float] | np.ndarray, *, resamples: int = RESAMPLES, seed: int = 0
) -> tuple[float, float]:
    """The 95 % percentile-bootstrap interval of the mean of ``values`` (finite ones; nan, nan with
    fewer than two). inf (a PSNR of identical frames) is kept: its interval is inf too."""
    v = np.asarray([x for x in values if x is not None and not math.isnan(x)], dtype=np.float64)
    if len(v) < 2:
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    means = v[rng.integers(0, len(v), (resamples, len(v)))].mean(axis=1)
    tail = (1 - LEVEL) / 2 * 100
    low, high = np.percentile(means, [tail, 100 - tail])
    return float(low), float(high)


@dataclass(frozen=True)
class Spread:
    """A result over seeds: mean, standard deviation (n − 1), min, max and how many seeds."""

    mean: float
    std: float
    low: float
    high: float
    n: int

    def text(self, fmt: str = "{:.2f}") -> str:
        if self.n == 0:
            return "—"
        if self.n == 1:
            return fmt.format(self.mean) + " (1 seed)"
        return f"{fmt.format(self.mean)} ± {fmt.replace('+', '').format(self.std)}"


def seed_spread(values: Sequence[float | None]) -> Spread:
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=np.float64)
    if not len(v):
        nan = float("nan")
        return Spread(nan, nan, nan, nan, 0)
    std = float(v.std(ddof=1)) if len(v) > 1 else float("nan")
    return Spread(float(v.mean()), std, float(v.min()), float(v.max()), len(v))


def differs(a: Spread, b: Spread) -> bool:
    """Whether the means of two settings differ by more than the larger of their seed spreads (standard
    deviations) and their ranges do not overlap: a difference a second seed would not reverse. False
    with fewer than two seeds on either side."""
    if a.n < 2 or b.n < 2 or not all(math.isfinite(x) for x in (a.mean, b.mean, a.std, b.std)):
        return False
    apart = abs(a.mean - b.mean) > max(a.std, b.std)
    return apart and (a.high < b.low or b.high < a.low)
