"""The camera's noise: Gaussian, spatially correlated and correlated between channels.

A real tactile camera's noise is not independent per pixel: demosaicing and compression
spread it over neighbours and across channels (measured on two real sensors: neighbour
correlation about 0.5-0.65 after a high-pass). ``SensorNoise`` makes such noise: white
Gaussian noise mixed between channels (``channel_correlation``), smoothed by a Gaussian of
``correlation_px`` pixels with its gain divided out (so each pixel keeps ``std_bgr``), at
the camera's own pixels (the profile's background) and then resized to the frame like the
background. ``measure`` estimates the same numbers from frames of one scene, and the
simulated noise measured that way gives back the profile's (tests/test_sensor_noise.py).

A profile of format 1 has one ``noise_std`` for independent noise at the frame's pixels:
``SensorNoise(std_bgr=(s, s, s), native=False)`` draws exactly what it drew before.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np

HIGH_PASS_PX = 2.0  # the estimator's high-pass: a frame minus its Gaussian blur of this σ (drift is smooth)
MAX_CORRELATION_PX = 8.0
CHANNEL_PAIRS = ((0, 1), (0, 2), (1, 2))  # (b, g), (b, r), (g, r)


@dataclass(frozen=True)
class SensorNoise:
    """``std_bgr``: grey levels per pixel and channel; ``correlation_px``: σ of the spatial
    correlation, in the camera's pixels (0: independent pixels); ``channel_correlation``: between
    (b, g), (b, r), (g, r); ``native``: defined at the background's resolution (else at the frame's)."""

    std_bgr: tuple[float, float, float]
    correlation_px: float = 0.0
    channel_correlation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    native: bool = True

    def __post_init__(self):
        if len(self.std_bgr) != 3 or not all(math.isfinite(v) and 0 <= v <= 50 for v in self.std_bgr):
            raise ValueError(f"noise std_bgr must be 3 numbers in [0, 50] grey levels, got {self.std_bgr}")
        if not (math.isfinite(self.correlation_px) and 0 <= self.correlation_px <= MAX_CORRELATION_PX):
            raise ValueError(
                f"noise correlation_px must be in [0, {MAX_CORRELATION_PX:g}] px, got {self.correlation_px}"
            )
        rho = self.channel_correlation
        if len(rho) != 3 or not all(math.isfinite(v) and -1 < v < 1 for v in rho):
            raise ValueError(f"noise channel_correlation must be 3 numbers in (-1, 1), got {rho}")
        if np.linalg.eigvalsh(self.channel_matrix()).min() <= 1e-6:
            raise ValueError(f"noise channel_correlation {tuple(rho)} is not a valid correlation between 3 channels")

    @property
    def silent(self) -> bool:
        return max(self.std_bgr) == 0

    @property
    def independent(self) -> bool:
        """The format-1 noise: the same std per channel, independent pixels and channels, at the frame."""
        return (
            not self.native
            and self.correlation_px == 0
            and not any(self.channel_correlation)
            and len(set(self.std_bgr)) == 1
        )

    def channel_matrix(self) -> np.ndarray:
        bg, br, gr = self.channel_correlation
        return np.array([[1.0, bg, br], [bg, 1.0, gr], [br, gr, 1.0]])

    def bank(
        self, rng: np.random.Generator, count: int, frame_hw: tuple[int, int], native_hw: tuple[int, int] | None
    ) -> np.ndarray:
        """(count, H, W, 3) float32 noise fields for frames of ``frame_hw``; ``native_hw`` is the
        camera's own size (the background's), where the noise is made before resizing."""
        h, w = frame_hw
        if self.independent:  # format 1: exactly the draws it always made
            return rng.normal(0.0, self.std_bgr[0], (count, h, w, 3)).astype(np.float32)
        hn, wn = native_hw if (self.native and native_hw is not None) else frame_hw
        white = rng.standard_normal((count, hn, wn, 3)).astype(np.float32)
        mix = np.linalg.cholesky(self.channel_matrix()).astype(np.float32)
        fields = white @ mix.T  # unit variance per channel, correlated between channels
        if self.correlation_px > 0:
            kernel, gain = _smoothing(self.correlation_px)
            for k in range(count):
                fields[k] = cv2.sepFilter2D(fields[k], -1, kernel, kernel, borderType=cv2.BORDER_REFLECT) / gain
        fields *= np.asarray(self.std_bgr, np.float32)
        if (hn, wn) != (h, w):
            fields = np.stack([cv2.resize(f, (w, h), interpolation=cv2.INTER_AREA) for f in fields])
        return np.ascontiguousarray(fields, dtype=np.float32)


@functools.cache
def _smoothing(sigma_px: float) -> tuple[np.ndarray, float]:
    """The 1-D Gaussian (its taps) and the std its 2-D separable filter leaves of unit white noise."""
    radius = max(1, int(math.ceil(4 * sigma_px)))
    kernel = cv2.getGaussianKernel(2 * radius + 1, sigma_px, cv2.CV_32F)
    return kernel, float(np.sum(kernel.astype(np.float64) ** 2))  # the 2-D filter leaves (Σk²)^½ · (Σk²)^½


@dataclass(frozen=True)
class NoiseStats:
    """What ``measure`` sees in the difference of two frames of one scene, after the high-pass."""

    std_bgr: tuple[float, float, float]  # of the difference, high-passed
    neighbour_correlation: float  # lag 1 along rows and columns, channels averaged
    channel_correlation: tuple[float, float, float]
    pixels: int


def _high_pass(img: np.ndarray) -> np.ndarray:
    img = img.astype(np.float32)
    return img - cv2.GaussianBlur(img, (0, 0), HIGH_PASS_PX)


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    den = math.sqrt(float((a * a).mean()) * float((b * b).mean()))
    return float((a * b).mean()) / den if den > 0 else 0.0


def difference_stats(first: np.ndarray, second: np.ndarray, mask: np.ndarray | None = None) -> NoiseStats:
    """Statistics of ``first - second`` (two frames of the same scene, BGR) high-passed, over
    ``mask`` (H, W) bool (default: all but an 8 px border)."""
    diff = _high_pass(first.astype(np.float32) - second.astype(np.float32))
    h, w = diff.shape[:2]
    if mask is None:
        mask = np.ones((h, w), bool)
    mask = mask.copy()
    mask[:8], mask[-8:], mask[:, :8], mask[:, -8:] = False, False, False, False
    both_x = mask[:, :-1] & mask[:, 1:]
    both_y = mask[:-1] & mask[1:]
    if mask.sum() < 1000 or both_x.sum() < 1000:
        raise ValueError(f"too few pixels away from the contact to measure the noise ({int(mask.sum())})")
    std = tuple(float(diff[..., c][mask].std()) for c in range(3))
    lag = np.mean(
        [_corr(diff[:, :-1, c][both_x], diff[:, 1:, c][both_x]) for c in range(3)]
        + [_corr(diff[:-1, :, c][both_y], diff[1:, :, c][both_y]) for c in range(3)]
    )
    chan = tuple(_corr(diff[..., i][mask], diff[..., j][mask]) for i, j in CHANNEL_PAIRS)
    return NoiseStats(std, float(lag), chan, int(mask.sum()))  # type: ignore[arg-type]


@functools.cache
def _seen_through_high_pass(sigma_px: float) -> tuple[float, float]:
    """For unit noise smoothed by ``sigma_px`` (as ``SensorNoise.bank``), the std and the neighbour
    correlation the high-pass leaves: computed from the filters' impulse response, no sampling."""
    size = 2 * int(math.ceil(4 * max(sigma_px, HIGH_PASS_PX))) + 33
    impulse = np.zeros((size, size), np.float32)
    impulse[size // 2, size // 2] = 1.0
    h: np.ndarray = impulse
    if sigma_px > 0:
        kernel, gain = _smoothing(sigma_px)
        h = np.asarray(cv2.sepFilter2D(impulse, -1, kernel, kernel, borderType=cv2.BORDER_CONSTANT)) / gain
    h = h - cv2.GaussianBlur(h, (0, 0), HIGH_PASS_PX, borderType=cv2.BORDER_CONSTANT)
    h = h.astype(np.float64)
    energy = float((h * h).sum())
    lag = float((h[:, :-1] * h[:, 1:]).sum()) / energy
    return math.sqrt(energy), lag


QUANTUM_VARIANCE = 1.0 / 12.0  # the rounding of a frame to whole grey levels: uniform, independent


def noise_from_stats(stats: NoiseStats) -> SensorNoise:
    """The ``SensorNoise`` (native) whose two independent frames, rounded to whole grey levels,
    give ``stats`` through the same high-pass: the rounding's share (independent, 1/12 per frame)
    taken out of the variances and covariances first; the correlation length from the neighbour
    correlation (bisection); the std from the high-passed std (a difference of two frames: √2
    times one frame's)."""
    kept0, lag0 = _seen_through_high_pass(0.0)
    rounding = 2 * QUANTUM_VARIANCE * kept0**2  # what the rounding of both frames leaves after the high-pass
    var = np.maximum(np.asarray(stats.std_bgr, float) ** 2 - rounding, 1e-6)
    mean_var = float(np.mean(np.asarray(stats.std_bgr, float) ** 2))
    lag = (stats.neighbour_correlation * mean_var - rounding * lag0) / max(float(var.mean()), 1e-6)
    target = min(lag, _seen_through_high_pass(MAX_CORRELATION_PX)[1])
    lo, hi = 0.0, MAX_CORRELATION_PX
    if target <= _seen_through_high_pass(0.0)[1]:
        sigma = 0.0
    else:
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if _seen_through_high_pass(mid)[1] < target else (lo, mid)
        sigma = round(float(0.5 * (lo + hi)), 3)
    kept = _seen_through_high_pass(sigma)[0]
    measured = np.asarray(stats.std_bgr, float) ** 2
    std = tuple(round(float(min(50.0, math.sqrt(v / 2) / kept)), 3) for v in var)
    rho = []
    for (i, j), r in zip(CHANNEL_PAIRS, stats.channel_correlation):
        cov = r * math.sqrt(measured[i] * measured[j])  # rounding is independent between channels
        rho.append(round(float(max(-0.95, min(0.95, cov / math.sqrt(var[i] * var[j])))), 3))
    try:
        return SensorNoise(std, sigma, tuple(rho))  # type: ignore[arg-type]
    except ValueError:  # measured channel correlations that no 3-channel noise has: keep the stds
        return SensorNoise(std, sigma)  # type: ignore[arg-type]
