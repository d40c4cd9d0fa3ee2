"""meta/stats.json as the ecosystem computes it: per episode, then aggregated over episodes.

Numeric features: min, max, mean, std, count and the quantiles q01 … q99 over the episode's frames, per
component. The camera: per channel (shape (3, 1, 1)), in [0, 1], over a sample of the episode's frames
(100 frames up to 500, then n^0.75), each taken every k-th pixel when its side is 300 px or more (about
150 px), RGB. Episodes are combined as the ecosystem does: min of mins, max of maxes, means weighted by
count, variances by the parallel formula, quantiles weighted by count.
"""

from __future__ import annotations

import numpy as np

QUANTILES = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}


def sample_count(n: int, low: int = 100, high: int = 10_000, power: float = 0.75) -> int:
    return max(min(low, n), min(int(n**power), high))


def sample_indices(n: int) -> list[int]:
    """Which of an episode's ``n`` frames the camera's statistics read, spread evenly."""
    return np.round(np.linspace(0, n - 1, sample_count(n))).astype(int).tolist()


def downsampled(frame_rgb: np.ndarray, target_px: int = 150, threshold_px: int = 300) -> np.ndarray:
    """(H, W, 3) taken every k-th pixel when its longer side reaches ``threshold_px``."""
    h, w = frame_rgb.shape[:2]
    if max(h, w) < threshold_px:
        return frame_rgb
    k = int(max(h, w) / target_px)
    return frame_rgb[::k, ::k]


def _stats(values: np.ndarray, axis, keepdims: bool) -> dict[str, np.ndarray]:
    out = {
        "min": np.min(values, axis=axis, keepdims=keepdims),
        "max": np.max(values, axis=axis, keepdims=keepdims),
        "mean": np.mean(values, axis=axis, keepdims=keepdims),
        "std": np.std(values, axis=axis, keepdims=keepdims),
    }
    for name, q in QUANTILES.items():
        out[name] = np.quantile(values, q, axis=axis, keepdims=keepdims)
    out["count"] = np.array([len(values)])
    return out


def numeric_stats(values: np.ndarray) -> dict[str, np.ndarray]:
    """(n, ...) values of one episode: statistics over the frames, per component (bool counts as 0/1)."""
    values = np.asarray(values, dtype=np.float64)
    return _stats(values, axis=0, keepdims=values.ndim == 1)


def image_stats(frames_rgb: np.ndarray) -> dict[str, np.ndarray]:
    """(k, H, W, 3) uint8 sampled frames of one episode: per channel, (3, 1, 1), in [0, 1]."""
    chw = np.asarray(frames_rgb, dtype=np.float64).transpose(0, 3, 1, 2)
    raw = _stats(chw, axis=(0, 2, 3), keepdims=True)
    return {k: v if k == "count" else v[0] / 255.0 for k, v in raw.items()}


def aggregate(episodes: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """One feature's statistics over several episodes' (each with its count)."""
    counts = np.stack([e["count"] for e in episodes]).astype(np.float64)
    total = counts.sum(axis=0)
    means = np.stack([e["mean"] for e in episodes])
    w = counts.reshape(counts.shape[:1] + (1,) * (means.ndim - 1))
    mean = (means * w).sum(axis=0) / total
    var = ((np.stack([e["std"] for e in episodes]) ** 2 + (means - mean) ** 2) * w).sum(axis=0) / total
    out = {
        "min": np.min(np.stack([e["min"] for e in episodes]), axis=0),
        "max": np.max(np.stack([e["max"] for e in episodes]), axis=0),
        "mean": mean,
        "std": np.sqrt(var),
    }
    for name in QUANTILES:
        out[name] = (np.stack([e[name] for e in episodes]) * w).sum(axis=0) / total
    out["count"] = total.astype(np.int64)
    return out


def as_json(stats: dict[str, dict[str, np.ndarray]]) -> dict:
    return {key: {k: np.asarray(v).tolist() for k, v in feature.items()} for key, feature in stats.items()}
