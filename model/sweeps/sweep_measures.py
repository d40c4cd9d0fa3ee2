"""What the force sweep measures on a frame, and the statistics it takes of those measures.

``measure_contact``: the contact in a frame as its change from the run's no-contact frame —
its area (pixels whose blurred change exceeds a threshold), centroid and shading (the mean
change inside it). ``contact_threshold``: that threshold for a part, from its real frames (a
third of their median peak change, at least ``THRESHOLD``), so that on a real sensor the
contact is measured and not the faint halo of the gel sinking around it or a lighting drift.
``spearman``, ``slope``, ``sign_consistency`` and ``power_exponent`` (k of area ∝ F^k) are what
the sweep reports of a measure against the swept force; ``frames_exponent`` gives k across a
set of real frames with a bootstrap interval.

numpy and OpenCV only: every measure is tested on synthetic frames without a network.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import cv2
import numpy as np
from numpy.typing import ArrayLike

THRESHOLD = 8.0  # 0–255: the least blurred change from the no-contact frame that counts as contact
PEAK_FRACTION = 1 / 3  # contact_threshold: this share of the part's median peak change


@dataclass
class ContactMeasure:
    area_px: int
    area_mm2: float
    centroid_x_mm: float  # from the image centre, +x to the right (columns)
    centroid_y_mm: float  # from the image centre, +y up (against the rows), as every other figure has it
    shading: float  # mean |change| (0–255, all channels) inside the contact; 0 without contact


def change_strength(image: np.ndarray, reference: np.ndarray, blur_px: float) -> tuple[np.ndarray, np.ndarray]:
    """(|change| per channel, its largest over channels) of ``image`` from ``reference``, both blurred
    with a Gaussian of σ ``blur_px``: float32 (H, W, 3) and (H, W)."""
    if image.shape != reference.shape:
        raise ValueError(f"image {image.shape} and no-contact reference {reference.shape} differ in shape")
    a: np.ndarray = image.astype(np.float32)
    b: np.ndarray = reference.astype(np.float32)
    if blur_px > 0:
        a = cv2.GaussianBlur(a, (0, 0), blur_px)
        b = cv2.GaussianBlur(b, (0, 0), blur_px)
    change = np.abs(a - b)
    return change, change.max(axis=2)


def measure_contact(
    image: np.ndarray,
    reference: np.ndarray,
    *,
    mm_per_px: float,
    threshold: float = THRESHOLD,
    blur_px: float = 1.0,
) -> ContactMeasure:
    """The contact in ``image`` as its change from the no-contact ``reference`` (both (H, W, 3) uint8,
    same size): both blurred with a Gaussian of σ ``blur_px`` (sensor noise and, for marker sensors,
    the markers' own motion stay below the threshold), the per-pixel change the largest over channels."""
    if not (math.isfinite(mm_per_px) and mm_per_px > 0):
        raise ValueError(f"mm_per_px must be a finite number > 0, got {mm_per_px}")
    change, strength = change_strength(image, reference, blur_px)
    mask = strength > threshold
    n = int(mask.sum())
    if n == 0:
        return ContactMeasure(0, 0.0, float("nan"), float("nan"), 0.0)
    rows, cols = np.nonzero(mask)
    weight = strength[mask]
    h, w = strength.shape
    cx = (float(np.average(cols, weights=weight)) - (w - 1) / 2) * mm_per_px
    cy = ((h - 1) / 2 - float(np.average(rows, weights=weight))) * mm_per_px  # +y up
    return ContactMeasure(n, n * mm_per_px**2, cx, cy, float(change[mask].mean()))


def contact_threshold(
    frames: Sequence[np.ndarray], references: Sequence[np.ndarray], blur_px: float
) -> tuple[float, float]:
    """(threshold, median peak change): PEAK_FRACTION of the median over ``frames`` of each frame's
    largest blurred change from its no-contact reference, and at least THRESHOLD. Frames without
    contact (peak below THRESHOLD) do not count; none in contact: THRESHOLD."""
    peaks = [float(change_strength(f, r, blur_px)[1].max()) for f, r in zip(frames, references)]
    touching = [p for p in peaks if p > THRESHOLD]
    if not touching:
        return THRESHOLD, float("nan")
    median = float(np.median(touching))
    return max(THRESHOLD, PEAK_FRACTION * median), median


def spearman(x: ArrayLike, y: ArrayLike) -> float:
    """Spearman's rank correlation (ties share their mean rank); nan when either side is constant
    or fewer than three finite pairs remain."""
    a, b = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    keep = np.isfinite(a) & np.isfinite(b)
    a, b = a[keep], b[keep]
    if len(a) < 3:
        return float("nan")
    ra, rb = _ranks(a), _ranks(b)
    if np.ptp(ra) == 0 or np.ptp(rb) == 0:
        return float("nan")
    return float(np.corrcoef(ra, rb)[0, 1])


def _ranks(v: np.ndarray) -> np.ndarray:
    order = np.argsort(v, kind="mergesort")
    ranks = np.empty(len(v))
    ranks[order] = np.arange(len(v), dtype=np.float64)
    for value in np.unique(v):  # ties: the mean of their ranks
        same = v == value
        if same.sum() > 1:
            ranks[same] = ranks[same].mean()
    return ranks


def slope(x: ArrayLike, y: ArrayLike) -> float:
    """Least-squares slope of y on x over the finite pairs (nan with fewer than two)."""
    a, b = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    keep = np.isfinite(a) & np.isfinite(b)
    if keep.sum() < 2 or np.ptp(a[keep]) == 0:
        return float("nan")
    return float(np.polyfit(a[keep], b[keep], 1)[0])


def sign_consistency(y: ArrayLike, expected_sign: float, tolerance: float = 0.0) -> float:
    """The fraction of successive steps of ``y`` that move with ``expected_sign`` (+1 or −1); steps
    smaller than ``tolerance`` count as not moving (so a flat response scores 0, not 1)."""
    d = np.diff(np.asarray(y, dtype=np.float64))
    d = d[np.isfinite(d)]
    if not len(d) or expected_sign == 0 or not math.isfinite(expected_sign):
        return float("nan")
    return float(np.mean(np.sign(expected_sign) * d > tolerance))


def power_exponent(force: ArrayLike, area: ArrayLike) -> float:
    """The exponent k of area ∝ force^k by least squares in log–log over positive pairs (Hertz: a
    sphere's contact radius grows as F^(1/3), its area as F^(2/3))."""
    f, a = np.asarray(force, dtype=np.float64), np.asarray(area, dtype=np.float64)
    keep = np.isfinite(f) & np.isfinite(a) & (f > 0) & (a > 0)
    return slope(np.log(f[keep]), np.log(a[keep])) if keep.sum() >= 2 else float("nan")


@dataclass(frozen=True)
class FramesExponent:
    """k of area ∝ Fz^k across real frames (each at its own pose), with a bootstrap interval."""

    k: float
    low: float  # 2.5th percentile of k over resamples of the frames
    high: float  # 97.5th
    rho: float  # Spearman ρ of area against Fz
    frames: int  # frames in contact that entered the fit
    fz_low: float  # their Fz range, N
    fz_high: float
    source: str = ""  # which frames, in words


def frames_exponent(fz: ArrayLike, area: ArrayLike, *, resamples: int = 2000, seed: int = 0) -> FramesExponent:
    """``power_exponent`` over frames with Fz > 0 and a contact, and its 95 % bootstrap interval over
    the frames (resampled with replacement, ``seed``: the same interval every time)."""
    f, a = np.asarray(fz, dtype=np.float64), np.asarray(area, dtype=np.float64)
    keep = np.isfinite(f) & np.isfinite(a) & (f > 0) & (a > 0)
    f, a = f[keep], a[keep]
    if len(f) < 3 or np.ptp(f) == 0:
        nan = float("nan")
        return FramesExponent(nan, nan, nan, nan, int(len(f)), *(_range(f)))
    rng = np.random.default_rng(seed)
    ks = []
    for _ in range(resamples):
        pick = rng.integers(0, len(f), len(f))
        k = power_exponent(f[pick], a[pick])
        if math.isfinite(k):
            ks.append(k)
    low, high = (float(v) for v in np.percentile(ks, [2.5, 97.5])) if ks else (float("nan"),) * 2
    return FramesExponent(power_exponent(f, a), low, high, spearman(f, a), int(len(f)), *_range(f))


def _range(f: np.ndarray) -> tuple[float, float]:
    return (float(f.min()), float(f.max())) if len(f) else (float("nan"), float("nan"))
