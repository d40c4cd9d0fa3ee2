"""Texture fidelity: is the fine texture of a pressed board in the generated frame?

MSE and SSIM over a whole frame barely notice whether a weave of 1 mm period is there:
its band holds little of a frame's energy. This measure looks only at that band, only
inside the contact, and compares a generated frame with the real one three ways:

- ``power_ratio``: the generated frame's power in the band over the real frame's
  (1 is right; a blurred frame gives much less than 1, a noisy one more).
- ``spectrum_corr``: the Pearson correlation of the two log power spectra over the
  band's 2-D frequency bins. It keeps orientation: a texture turned by 30° puts its
  peaks at other bins and scores low although its power is the same.
- ``hp_ssim``: SSIM (Gaussian window, σ = 1.5 px) of the two frames' high-pass parts
  (the frame minus its Gaussian blur at the band's longest period), over the contact,
  with the real high-pass part's 1–99 % range as the data range (255 would call any
  faint texture perfect).

``score`` folds them into one number in [0, 1]: the mean of exp(−|ln power_ratio|),
max(spectrum_corr, 0) and max(hp_ssim, 0); 1 only when all three are perfect.

Frames are (H, W, 3) or (H, W) arrays in 0–255; the contact is a boolean (H, W) mask;
the band is given as texture periods in mm with the frame's mm per pixel. numpy and
OpenCV only: no torch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

MIN_CONTACT_PX = 64  # fewer contact pixels than this carry no spectrum worth the name
SSIM_SIGMA_PX = 1.5
K1, K2 = 0.01, 0.03


@dataclass(frozen=True)
class TextureBand:
    """Texture periods from ``shortest_mm`` to ``longest_mm`` on a frame of ``mm_per_px``."""

    shortest_mm: float
    longest_mm: float
    mm_per_px: float

    def __post_init__(self) -> None:
        for name in ("shortest_mm", "longest_mm", "mm_per_px"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"texture band: {name} = {value!r}, expected a finite number > 0")
        if self.shortest_mm > self.longest_mm:
            raise ValueError(
                f"texture band: shortest_mm {self.shortest_mm:g} > longest_mm {self.longest_mm:g}, "
                "expected shortest ≤ longest"
            )

    @property
    def shortest_px(self) -> float:
        return self.shortest_mm / self.mm_per_px

    @property
    def longest_px(self) -> float:
        return self.longest_mm / self.mm_per_px

    def resolved(self) -> bool:
        """Whether the frame can show the band at all: its shortest period spans ≥ 2 px (Nyquist)."""
        return self.shortest_px >= 2.0


@dataclass(frozen=True)
class TextureScore:
    power_ratio: float
    spectrum_corr: float
    hp_ssim: float

    @property
    def score(self) -> float:
        ratio = math.exp(-abs(math.log(self.power_ratio))) if self.power_ratio > 0 else 0.0
        return (ratio + max(self.spectrum_corr, 0.0) + max(self.hp_ssim, 0.0)) / 3.0

    def as_dict(self) -> dict[str, float]:
        return {
            "power_ratio": self.power_ratio,
            "spectrum_corr": self.spectrum_corr,
            "hp_ssim": self.hp_ssim,
            "texture_score": self.score,
        }


def _grey(frame: np.ndarray) -> np.ndarray:
    a = np.asarray(frame, dtype=np.float64)
    if a.ndim == 3:
        a = a.mean(axis=2)
    if a.ndim != 2:
        raise ValueError(f"texture measure: a frame of shape {np.shape(frame)}, expected (H, W) or (H, W, 3)")
    if not np.all(np.isfinite(a)):
        raise ValueError("texture measure: the frame holds NaN or inf")
    return a


def _box(mask: np.ndarray) -> tuple[slice, slice]:
    rows, cols = np.nonzero(mask)
    return slice(rows.min(), rows.max() + 1), slice(cols.min(), cols.max() + 1)


def _window(mask: np.ndarray, taper_px: float) -> np.ndarray:
    """The contact mask with its edge tapered, so that the mask's own edge adds little power."""
    w = cv2.GaussianBlur(mask.astype(np.float64), (0, 0), max(taper_px, 0.5))
    return w * mask


def band_spectrum(frame: np.ndarray, mask: np.ndarray, band: TextureBand) -> tuple[np.ndarray, np.ndarray]:
    """The power spectrum of the frame's contact (mean removed, edge tapered) and the boolean
    map of its frequency bins inside the band, both (h, w) over the contact's bounding box."""
    grey = _grey(frame)
    rs, cs = _box(mask)
    crop, m = grey[rs, cs], mask[rs, cs]
    w = _window(m, band.longest_px / 4)
    mean = float((crop * w).sum() / max(w.sum(), 1e-12))
    power = np.abs(np.fft.fft2((crop - mean) * w)) ** 2
    fy = np.fft.fftfreq(crop.shape[0])[:, None]
    fx = np.fft.fftfreq(crop.shape[1])[None, :]
    f = np.hypot(fy, fx)  # cycles per pixel
    in_band = (f >= 1.0 / band.longest_px) & (f <= min(1.0 / band.shortest_px, 0.5))
    return power, in_band


def _highpass(grey: np.ndarray, band: TextureBand) -> np.ndarray:
    return grey - cv2.GaussianBlur(grey, (0, 0), band.longest_px / 2, borderType=cv2.BORDER_REFLECT)


def _ssim_map(x: np.ndarray, y: np.ndarray, data_range: float) -> np.ndarray:
    def g(a: np.ndarray) -> np.ndarray:
        return cv2.GaussianBlur(a, (0, 0), SSIM_SIGMA_PX, borderType=cv2.BORDER_REFLECT)

    c1, c2 = (K1 * data_range) ** 2, (K2 * data_range) ** 2
    mx, my = g(x), g(y)
    vx, vy, cxy = g(x * x) - mx * mx, g(y * y) - my * my, g(x * y) - mx * my
    return ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))


def texture_score(real: np.ndarray, generated: np.ndarray, contact: np.ndarray, band: TextureBand) -> TextureScore:
    """The three texture measures of ``generated`` against ``real`` inside ``contact``."""
    mask = np.asarray(contact, dtype=bool)
    r, g = _grey(real), _grey(generated)
    if r.shape != g.shape or mask.shape != r.shape:
        raise ValueError(
            f"texture measure: real {r.shape}, generated {g.shape} and contact {mask.shape} differ, expected one (H, W)"
        )
    if int(mask.sum()) < MIN_CONTACT_PX:
        raise ValueError(f"texture measure: the contact has {int(mask.sum())} px, expected ≥ {MIN_CONTACT_PX}")
    if not band.resolved():
        raise ValueError(
            f"texture measure: the shortest period {band.shortest_mm:g} mm is {band.shortest_px:.2f} px on this frame, "
            "expected ≥ 2 px: the frame cannot show the texture (generate at a higher resolution)"
        )
    pr, in_band = band_spectrum(r, mask, band)
    pg, _ = band_spectrum(g, mask, band)
    if not in_band.any():
        raise ValueError("texture measure: the contact is smaller than one period of the band")
    real_power, made_power = float(pr[in_band].sum()), float(pg[in_band].sum())
    ratio = made_power / real_power if real_power > 0 else (1.0 if made_power == 0 else math.inf)
    lr, lg = np.log10(pr[in_band] + 1e-9), np.log10(pg[in_band] + 1e-9)
    corr = float(np.corrcoef(lr, lg)[0, 1]) if lr.std() > 0 and lg.std() > 0 else 0.0
    hr, hg = _highpass(r, band), _highpass(g, band)
    lo, hi = np.percentile(hr[mask], [1, 99])
    ssim = float(_ssim_map(hr, hg, max(float(hi - lo), 1e-6))[mask].mean())
    return TextureScore(ratio, corr, ssim)


def radial_profile(power: np.ndarray, bins: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """Power averaged over rings of frequency (cycles per pixel, 0–0.5): for the spectra figure."""
    fy = np.fft.fftfreq(power.shape[0])[:, None]
    fx = np.fft.fftfreq(power.shape[1])[None, :]
    f = np.hypot(fy, fx).ravel()
    edges = np.linspace(0.0, 0.5, bins + 1)
    which = np.digitize(f, edges) - 1
    keep = (which >= 0) & (which < bins)
    total = np.bincount(which[keep], weights=power.ravel()[keep], minlength=bins)
    count = np.bincount(which[keep], minlength=bins)
    centres = (edges[:-1] + edges[1:]) / 2
    return centres, total / np.maximum(count, 1)
