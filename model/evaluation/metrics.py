"""The evaluation metrics the field uses, as docs/reference.md ("Metrics") defines them.

Images are uint8-range (0–255), (H, W, 3), compared over all channels and the whole
image. numpy/OpenCV only: evaluating needs no torch.

- MSE, MAE: mean over every pixel and channel.
- PSNR = 10·log10(255² / MSE) (inf for identical images).
- SSIM (Wang et al. 2004): Gaussian window 11×11, σ = 1.5, K1 = 0.01, K2 = 0.03,
  L = 255, population (not sample) covariances, averaged over channels; equal to
  scikit-image's structural_similarity(gaussian_weights=True, sigma=1.5,
  use_sample_covariance=False, data_range=255), whose border handling it follows.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

L = 255.0
K1, K2 = 0.01, 0.03
SIGMA = 1.5
WINDOW = 11


def _pair(a, b) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"images differ in shape: {a.shape} vs {b.shape}")
    return a, b


def mse(a, b) -> float:
    a, b = _pair(a, b)
    return float(np.mean((a - b) ** 2))


def mae(a, b) -> float:
    a, b = _pair(a, b)
    return float(np.mean(np.abs(a - b)))


def psnr(a, b) -> float:
    m = mse(a, b)
    return math.inf if m == 0 else 10.0 * math.log10(L * L / m)


def _gaussian(x: np.ndarray) -> np.ndarray:
    # scikit-image: a truncated Gaussian of 11 taps (truncate = 3.5σ), 'reflect' borders.
    return cv2.GaussianBlur(x, (WINDOW, WINDOW), SIGMA, borderType=cv2.BORDER_REFLECT)


def ssim_map(a, b) -> np.ndarray:
    """SSIM at every pixel, averaged over channels: (H, W) float64, the windows overhanging the border
    reflected (as scikit-image computes them before it crops that border)."""
    a, b = _pair(a, b)
    if a.ndim == 2:
        a, b = a[..., None], b[..., None]
    c1, c2 = (K1 * L) ** 2, (K2 * L) ** 2
    values = []
    for ch in range(a.shape[2]):
        x, y = a[..., ch], b[..., ch]
        mx, my = _gaussian(x), _gaussian(y)
        vx = _gaussian(x * x) - mx * mx
        vy = _gaussian(y * y) - my * my
        cxy = _gaussian(x * y) - mx * my
        values.append(((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2)))
    return np.mean(values, axis=0)


def ssim(a, b) -> float:
    pad = (WINDOW - 1) // 2
    return float(ssim_map(a, b)[pad:-pad, pad:-pad].mean())  # scikit-image crops the border the window overhangs


def image_metrics(real, generated) -> dict[str, float]:
    return {
        "mse": mse(real, generated),
        "mae": mae(real, generated),
        "ssim": ssim(real, generated),
        "psnr": psnr(real, generated),
    }
