"""Scores of the contact itself: the image metrics near it, and its size under the lightest loads.

Whole-frame metrics at small sizes are mostly background: a method that gets the untouched gel
right scores well even when the contact is wrong. So beside them, each metric is taken again
inside a stated radius (``NEAR_RADIUS_MM``) around the contact that the real frame shows — the
pixels whose blurred change from the run's no-contact frame exceeds the part's contact threshold
(model/sweeps/sweep_measures.py), grown by the radius — the same pixels for every method. A frame whose
real contact is not seen has no near-contact value (the count is said).

The light-load row: over the frames of smallest Fz (the lightest ``LIGHT_SHARE`` of the pressed
frames, at least 3 where there are), each method's contact area (measured as the force sweep
measures it) against the real frames', as the ratio of the mean areas with a bootstrap interval
over frames; a generated contact twice too large reads 2.0.

numpy and OpenCV only: tested on synthetic frames without a network.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import cv2
import numpy as np

from model.evaluation.eval_results import Row
from model.evaluation.intervals import RESAMPLES, bootstrap_interval
from model.evaluation.metrics import L, ssim_map
from model.sweeps.sweep_measures import change_strength, contact_threshold, measure_contact

NEAR_RADIUS_MM = 3.0  # the near-contact region: this far around the contact the real frame shows
LIGHT_SHARE = 0.2  # the light-load row: this share of the pressed frames, the lightest
LIGHT_MIN_FRAMES = 3


@dataclass
class Contacts:
    """What the real frames of a part say of their contact, at the evaluated size."""

    regions: list[np.ndarray | None]  # each frame's near-contact pixels (bool H×W); None: no contact seen
    references: list[np.ndarray]  # each frame's run's no-contact frame
    mm_per_px: list[float]
    fz_N: list[float]
    threshold: float  # 0–255, the blurred change that counts as contact
    blur_px: float
    radius_mm: float
    real_area_mm2: list[float] = field(default_factory=list)

    @property
    def seen(self) -> int:
        return sum(r is not None for r in self.regions)


def find_contacts(
    real: Sequence[np.ndarray],
    references: Sequence[np.ndarray],
    mm_per_px: Sequence[float],
    fz_N: Sequence[float],
    *,
    blur_px: float,
    radius_mm: float = NEAR_RADIUS_MM,
) -> Contacts:
    """Each real frame's contact (its change from ``references`` above the part's threshold) and the
    pixels within ``radius_mm`` of it."""
    if not (math.isfinite(radius_mm) and radius_mm > 0):
        raise ValueError(f"near-contact radius must be a finite number of mm > 0, got {radius_mm}")
    threshold, _ = contact_threshold(real, references, blur_px)
    regions: list[np.ndarray | None] = []
    areas = []
    for frame, ref, scale in zip(real, references, mm_per_px):
        _, strength = change_strength(frame, ref, blur_px)
        contact = strength > threshold
        areas.append(float(contact.sum()) * scale * scale)
        if not contact.any():
            regions.append(None)
            continue
        outside = (~contact).astype(np.uint8)
        distance_px = cv2.distanceTransform(outside, cv2.DIST_L2, 5)
        regions.append(distance_px * scale <= radius_mm)
    return Contacts(regions, list(references), list(mm_per_px), list(fz_N), threshold, blur_px, radius_mm, areas)


def region_metrics(real: np.ndarray, made: np.ndarray, region: np.ndarray) -> dict[str, float]:
    """MSE, MAE, SSIM and PSNR over the pixels of ``region`` (all channels); SSIM the per-pixel map's
    mean there (model/evaluation/metrics.py ``ssim_map``)."""
    a, b = real.astype(np.float64)[region], made.astype(np.float64)[region]
    mse = float(np.mean((a - b) ** 2))
    return {
        "mse": mse,
        "mae": float(np.mean(np.abs(a - b))),
        "ssim": float(ssim_map(real, made)[region].mean()),
        "psnr": math.inf if mse == 0 else 10.0 * math.log10(L * L / mse),
    }


def near_row(setting: str, real: Sequence[np.ndarray], made: Sequence[np.ndarray], contacts: Contacts) -> Row | None:
    """A method's metrics inside the near-contact regions (frames without a seen contact left out);
    None when no frame has one."""
    values = [region_metrics(r, m, g) for r, m, g in zip(real, made, contacts.regions) if g is not None]
    if not values:
        return None
    per_frame = {k: [v[k] for v in values] for k in ("mse", "mae", "ssim", "psnr")}
    mean = {k: float(np.mean(v)) for k, v in per_frame.items()}
    row = Row(setting, mean["mse"], mean["mae"], mean["ssim"], mean["psnr"], None, 0.0, len(values))
    row.per_frame = per_frame
    row.ci = {k: bootstrap_interval(v) for k, v in per_frame.items()}
    return row


def light_frames(contacts: Contacts) -> list[int]:
    """The frames of the light-load row: the lightest LIGHT_SHARE of those pressed (Fz > 0), at least
    LIGHT_MIN_FRAMES where there are that many, in order of Fz."""
    pressed = [i for i, f in enumerate(contacts.fz_N) if math.isfinite(f) and f > 0]
    pressed.sort(key=lambda i: contacts.fz_N[i])
    n = max(min(LIGHT_MIN_FRAMES, len(pressed)), math.ceil(LIGHT_SHARE * len(pressed)))
    return pressed[:n]


def light_load(setting: str, made: Sequence[np.ndarray], contacts: Contacts) -> dict | None:
    """The method's mean contact area over the light-load frames against the real frames' (mm²), and
    their ratio with a 95 % bootstrap interval over those frames (nan where the real area is 0)."""
    frames = light_frames(contacts)
    if not frames:
        return None
    made_mm2 = np.array(
        [
            measure_contact(
                made[i],
                contacts.references[i],
                mm_per_px=contacts.mm_per_px[i],
                threshold=contacts.threshold,
                blur_px=contacts.blur_px,
            ).area_mm2
            for i in frames
        ]
    )
    real_mm2 = np.array([contacts.real_area_mm2[i] for i in frames])
    ratio, low, high = _ratio(made_mm2, real_mm2)
    return {
        "method": setting,
        "frames": len(frames),
        "fz_low_N": float(contacts.fz_N[frames[0]]),
        "fz_high_N": float(contacts.fz_N[frames[-1]]),
        "area_mm2": float(made_mm2.mean()),
        "real_area_mm2": float(real_mm2.mean()),
        "ratio": ratio,
        "ratio_ci": (low, high),
    }


def _ratio(made: np.ndarray, real: np.ndarray) -> tuple[float, float, float]:
    if real.sum() <= 0:
        return (float("nan"),) * 3
    ratio = float(made.mean() / real.mean())
    if len(made) < 2:
        return ratio, float("nan"), float("nan")
    pick = np.random.default_rng(0).integers(0, len(made), (RESAMPLES, len(made)))
    denominators = real[pick].mean(axis=1)
    ok = denominators > 0
    ratios = made[pick].mean(axis=1)[ok] / denominators[ok]
    low, high = np.percentile(ratios, [2.5, 97.5])
    return ratio, float(low), float(high)
