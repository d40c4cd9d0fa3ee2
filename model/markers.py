"""Marker displacement error: how far generated markers sit from the real ones.

docs/reference.md, "Metrics": markers found by adaptive thresholding and contour detection;
the central 18×18 = 324 markers matched between the real and the generated frame;
the error is the sum (and the mean per marker) of the Euclidean distances between
matched centroids, in pixels. Markers are found in each frame independently, so
the metric needs no simulator and applies to real sensors as well.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

CENTRAL = 18


def find_markers(
    image: np.ndarray, *, block: int = 21, offset: float = 12.0, min_area: float = 3.0, max_area_frac: float = 0.01
) -> np.ndarray:
    """(n, 2) marker centroids (col, row) in pixels: dark blobs on the gel."""
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    mask = cv2.adaptiveThreshold(gray, 255, cv2.ADAPTIVE_THRESH_GAUSSIAN_C, cv2.THRESH_BINARY_INV, block, offset)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    max_area = max_area_frac * gray.size
    out = []
    for c in contours:
        m = cv2.moments(c)
        if min_area <= m["m00"] <= max_area:
            out.append((m["m10"] / m["m00"], m["m01"] / m["m00"]))
    return np.array(out, dtype=np.float64).reshape(-1, 2)


def central(markers: np.ndarray, shape: tuple[int, int], n: int = CENTRAL) -> np.ndarray:
    """The n×n markers nearest the image centre (by rank, not by a fixed radius)."""
    if len(markers) < n * n:
        raise ValueError(f"found {len(markers)} markers, fewer than the {n}x{n} central ones needed")
    centre = np.array([(shape[1] - 1) / 2, (shape[0] - 1) / 2])
    d = np.max(np.abs(markers - centre), axis=1)  # Chebyshev: the central square of the grid
    return markers[np.argsort(d, kind="stable")[: n * n]]


@dataclass(frozen=True)
class MarkerError:
    total_px: float
    per_marker_px: float
    matched: int


def marker_error(real: np.ndarray, generated: np.ndarray, n: int = CENTRAL) -> MarkerError:
    """Sum and mean of distances between the real frame's central n×n markers and their
    matches (minimum-cost assignment) among the generated frame's markers."""
    a, b = marker_flow(real, generated, n)
    distances = np.linalg.norm(a - b, axis=1)
    return MarkerError(float(distances.sum()), float(distances.mean()), int(len(a)))


def marker_flow(reference: np.ndarray, image: np.ndarray, n: int = CENTRAL) -> tuple[np.ndarray, np.ndarray]:
    """The ``reference`` frame's central n×n marker centroids and their minimum-cost matches
    among ``image``'s markers, (n², 2) each (col, row). From a no-contact reference frame,
    this is the markers' motion."""
    start = central(find_markers(reference), reference.shape[:2], n)
    found = find_markers(image)
    if len(found) == 0:
        raise ValueError("no markers found in the frame compared")
    cost = np.linalg.norm(start[:, None, :] - found[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(cost)
    return start[rows], found[cols]
