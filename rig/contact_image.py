"""Where a contact is in a tactile frame, and how far it moved between two frames (numpy and OpenCV).

Both work on the **change**: |frame − reference| (the reference is the gel with nothing
touching), smoothed and summed over the colour channels, after a grey closing has filled in
the dark markers of a marker gel (a marker that moves would otherwise be a change too).

- ``centre``: the centroid of the contact's area: the connected region around the strongest
  change where the change exceeds ``AREA_FRACTION`` of its peak (each pixel counted once, so a
  brighter side of the contact does not pull it). On the simulated gel (rgb, rgb_markers,
  white_markers; a 10 mm sphere 1 mm deep, within 2 mm of the middle) within 1.4 px of the true
  centre; the point-symmetry of the change (its correlation with itself turned 180°) was 3-6 px
  off on the rgb gel, whose lights shade one side of a contact more than the other.
- ``shift``: phase correlation of two changes (within 0.3 px on rgb and rgb_markers), unless its
  peak is weak (below ``MIN_RESPONSE``: a white-light marker gel, whose change is mostly the marker
  grid, so phase correlation locks onto the grid) or it disagrees with the difference of the two
  centres by more than ``AGREE_PX``; then that difference.
"""

from __future__ import annotations

import numpy as np

MARKER_PX = 11  # the closing's size: larger than a marker, smaller than a contact
BLUR_PX = 3.0
MIN_CHANGE = 15.0  # peak of the summed change below this is noise and exposure drift, not a press
AREA_FRACTION = 0.1  # the contact's area: where the change exceeds this part of its peak
AGREE_PX = 3.0
MIN_RESPONSE = 0.2  # phase correlation's peak below this: no single shift explains the two changes


class GelContactImages:
    """``rig.axis_check.ContactImages`` for a tactile gel (RGB or white light, with or without markers)."""

    def centre(self, reference: np.ndarray, frame: np.ndarray) -> tuple[float, float] | None:
        return contact_centre(_change(reference, frame))

    def shift(self, reference: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
        import cv2

        change_a, change_b = _change(reference, a), _change(reference, b)
        (dx, dy), response = cv2.phaseCorrelate(change_a, change_b)
        ca, cb = contact_centre(change_a), contact_centre(change_b)
        if ca is not None and cb is not None:
            by_centres = (cb[0] - ca[0], cb[1] - ca[1])
            if response < MIN_RESPONSE or np.hypot(dx - by_centres[0], dy - by_centres[1]) > AGREE_PX:
                return by_centres
        return (float(dx), float(dy))


def contact_centre(change: np.ndarray) -> tuple[float, float] | None:
    """(column, row) of the centroid of the contact's area in a change map; None when nothing
    changed above the noise."""
    import cv2

    peak = float(change.max())
    if peak < MIN_CHANGE:
        return None
    area = (change >= max(AREA_FRACTION * peak, MIN_CHANGE / 2)).astype(np.uint8)
    _, labels = cv2.connectedComponents(area)
    row, col = np.unravel_index(int(np.argmax(change)), change.shape)
    rows, cols = np.nonzero(labels == labels[row, col])  # the region holding the strongest change
    return (float(cols.mean()), float(rows.mean()))


def _colour(image: np.ndarray) -> np.ndarray:
    return image[..., None] if image.ndim == 2 else image  # a grey camera: one channel


def _change(reference: np.ndarray, frame: np.ndarray) -> np.ndarray:
    import cv2

    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (MARKER_PX, MARKER_PX))
    ref, now = (
        _colour(cv2.morphologyEx(img, cv2.MORPH_CLOSE, kernel)).astype(np.float32) for img in (reference, frame)
    )
    diff = cv2.GaussianBlur(now - ref, (0, 0), BLUR_PX).reshape(now.shape)
    return np.abs(diff).sum(axis=2).astype(np.float64)
