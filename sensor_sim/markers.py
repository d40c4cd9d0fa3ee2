"""Markers on the gel: find them in a frame, match them to a reference frame's.

Image analysis of a tactile frame, real or simulated (numpy, OpenCV, SciPy; no torch), used
by the model's marker metrics (model/evaluation/markers.py) and the console's marker-flow arrows.
Markers are dark blobs found by adaptive thresholding and contours. The metrics match a
reference frame's markers to a frame's at the least total distance (``marker_flow``); the
console's live arrows pair mutual nearest neighbours (``displacements``), much faster.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

CENTRAL = 18


def find_markers(
    image: np.ndarray, *, block: int = 21, offset: float = 12.0, min_area: float = 3.0, max_area_frac: float = 0.01
) -> np.ndarray:
    """(n, 2) marker centroids (col, row) in pixels: dark blobs on the gel.

    Every outer boundary counts, also one inside another blob's hole: a flat punch's dark rim
    is one large ring around the contact (rejected by its size), and the markers inside it
    are markers still (only outermost contours would lose them all)."""
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    mask = cv2.adaptiveThreshold(gray, 255, cv2.ADAPTIVE_THRESH_GAUSSIAN_C, cv2.THRESH_BINARY_INV, block, offset)
    contours, hierarchy = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    max_area = max_area_frac * gray.size
    out = []
    for c, h in zip(contours, hierarchy[0] if hierarchy is not None else []):
        if h[3] >= 0:  # a hole's boundary, not a blob's
            continue
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


def match(start: np.ndarray, found: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-cost (total distance) matches of ``start`` markers among ``found``: the matched
    rows of each, (m, 2) with m = min(len(start), len(found))."""
    if len(start) == 0 or len(found) == 0:
        return np.zeros((0, 2)), np.zeros((0, 2))
    cost = np.linalg.norm(start[:, None, :] - found[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(cost)
    return start[rows], found[cols]


def marker_flow(reference: np.ndarray, image: np.ndarray, n: int = CENTRAL) -> tuple[np.ndarray, np.ndarray]:
    """The ``reference`` frame's central n×n marker centroids and their minimum-cost matches
    among ``image``'s markers, (n², 2) each (col, row). From a no-contact reference frame,
    this is the markers' motion."""
    start = central(find_markers(reference), reference.shape[:2], n)
    found = find_markers(image)
    if len(found) == 0:
        raise ValueError("no markers found in the frame compared")
    return match(start, found)


def spacing_px(markers: np.ndarray) -> float:
    """The median distance from a marker to its nearest neighbour (the grid pitch); NaN for
    fewer than two markers."""
    if len(markers) < 2:
        return float("nan")
    distances, _ = cKDTree(markers).query(markers, k=2)
    return float(np.median(distances[:, 1]))


SURE_FRAC = 0.25  # a pair this close (of the pitch) is certain when no marker moves over 0.75 of it


def displacements(
    reference_markers: np.ndarray, image: np.ndarray, *, max_frac: float = 0.7, pitch_px: float | None = None
) -> np.ndarray:
    """Every reference marker followed into ``image``: (m, 4) rows of x, y (reference position,
    px) and dx, dy (its motion, px). Pairs of mutual nearest neighbours closer than SURE_FRAC of
    the grid pitch (``pitch_px``, default measured on the reference) are taken as they are (the
    markers away from the contact); the rest are matched at the least total distance, as
    ``match`` does, which keeps a sheared patch together where nearest neighbours would jump to
    the next marker's place. Pairs over ``max_frac`` of the pitch apart are dropped: beyond that
    a marker cannot be told from its neighbour's place."""
    found = find_markers(image)
    if len(reference_markers) == 0 or len(found) == 0:
        return np.zeros((0, 4))
    pitch = spacing_px(reference_markers) if pitch_px is None else pitch_px
    if not np.isfinite(pitch):
        a, b = match(reference_markers, found)
        return np.hstack([a, b - a])
    distance, j = cKDTree(found).query(reference_markers, distance_upper_bound=SURE_FRAC * pitch)
    near = np.isfinite(distance)
    _, back = cKDTree(reference_markers).query(found)
    sure = np.zeros(len(reference_markers), dtype=bool)
    sure[near] = back[j[near]] == np.flatnonzero(near)
    taken = np.zeros(len(found), dtype=bool)
    taken[j[sure]] = True
    a_rest, b_rest = match(reference_markers[~sure], found[~taken])
    a = np.vstack([reference_markers[sure], a_rest])
    d = np.vstack([found[j[sure]], b_rest]) - a
    keep = np.linalg.norm(d, axis=1) <= max_frac * pitch
    return np.hstack([a[keep], d[keep]])
