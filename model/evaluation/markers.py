"""Marker displacement error: how far generated markers sit from the real ones.

docs/reference.md, "Metrics": markers found by adaptive thresholding and contour detection;
the central 18×18 = 324 markers matched between the real and the generated frame;
the error is the sum (and the mean per marker) of the Euclidean distances between
matched centroids, in pixels. Markers are found in each frame independently, so
the metric needs no simulator and applies to real sensors as well. Finding and matching
markers is in sensor_sim/markers.py (light: the web console draws marker flow with it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensor_sim.markers import CENTRAL, central, find_markers, marker_flow

__all__ = ["CENTRAL", "MarkerError", "central", "find_markers", "marker_error", "marker_flow"]


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
