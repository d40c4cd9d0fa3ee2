"""The texture figure of a board report: radial power spectra inside the contact (real,
generated, and any baseline rows), the texture band shaded, and crops of the frames at full
resolution (each pixel drawn as a block, never smoothed) so that a weave one or two pixels
wide is visible as pixels."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from model.evaluation.texture_measure import TextureBand, band_spectrum, radial_profile

CROP_PX = 96  # the crop's side in frame pixels, around the contact's centre
BLOCK_PX = 3  # each frame pixel drawn as a BLOCK_PX × BLOCK_PX block


def _crop(frame: np.ndarray, mask: np.ndarray) -> np.ndarray:
    rows, cols = np.nonzero(mask)
    cy, cx = int(rows.mean()), int(cols.mean())
    h, w = frame.shape[:2]
    half = min(CROP_PX // 2, h // 2, w // 2)
    y0 = min(max(cy - half, 0), h - 2 * half)
    x0 = min(max(cx - half, 0), w - 2 * half)
    return frame[y0 : y0 + 2 * half, x0 : x0 + 2 * half]


def texture_figure(frames: dict[str, np.ndarray], mask: np.ndarray, band: TextureBand, path: Path, title: str) -> None:
    """``frames``: {label: (H, W, 3) uint8 BGR}, the real frame first. Writes a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = list(frames)
    fig = plt.figure(figsize=(3.2 * max(len(labels), 3), 6.6))
    grid = fig.add_gridspec(2, len(labels), height_ratios=[1.1, 1.0])
    ax = fig.add_subplot(grid[0, :])
    for label in labels:
        power, _ = band_spectrum(frames[label], mask, band)
        f_px, p = radial_profile(power)
        keep = f_px > 0
        ax.loglog(f_px[keep] / band.mm_per_px, p[keep] + 1e-9, label=label)
    ax.axvspan(1.0 / band.longest_mm, 1.0 / band.shortest_mm, color="0.85", zorder=0, label="texture band")
    nyquist = 0.5 / band.mm_per_px
    ax.axvline(nyquist, color="0.4", ls=":", label=f"frame's Nyquist ({nyquist:.2g} cycles/mm)")
    ax.set_xlabel("spatial frequency, cycles per mm")
    ax.set_ylabel("power inside the contact (grey levels² per bin)")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8, ncol=2)
    for i, label in enumerate(labels):
        tile = fig.add_subplot(grid[1, i])
        crop = _crop(np.asarray(frames[label])[..., ::-1], mask)  # BGR → RGB for matplotlib
        tile.imshow(np.kron(crop, np.ones((BLOCK_PX, BLOCK_PX, 1), dtype=crop.dtype)), interpolation="nearest")
        side_mm = crop.shape[0] * band.mm_per_px
        words = label.replace("baseline: ", "").replace(" (the real frame at the model's resolution)", "")
        tile.set_title(f"{words}\n{crop.shape[0]} px = {side_mm:.1f} mm, pixels as blocks", fontsize=8)
        tile.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
