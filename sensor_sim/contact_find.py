"""Where a ball press is in a frame, from the frame alone: its centre and contact radius in pixels.

    contact = find_contact(background, image)   # Contact(centre_x_px, centre_y_px, radius_px)

Two steps, neither needing a light model: the changed region (where the colour differs from
the background by more than a third of its peak: its weighted centroid and its size), then
the rim: along rays from that centre, the radius where the change varies fastest (the contact
edge, where the ball leaves the gel), and a least-squares circle through those points. The
calibration refines the result by rendering (sensor_sim/calibration.py); a press whose rim
the frame does not show (cut by the frame's edge, or too small) keeps its centroid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import map_coordinates

# The visibly changed region reaches past the contact (the gel relaxes around it): the contact
# radius is about this share of the region's equivalent radius (0.70–0.77 on synthetic presses).
RADIUS_OF_REGION = 0.75
# The rim (where the colour changes fastest) lies just outside the contact edge (the optical blur,
# the gel leaving the ball): the contact radius is this share of the rim's, measured on presses
# rendered through the solver (0.906-0.916) and on the real GelSight's published radii (~0.92).
RIM_TO_CONTACT = 0.91
RAYS = 180
MIN_RIM_PX = 6.0  # a contact smaller than this has no rim to find


class CalibrationError(ValueError):
    """Presses that cannot be fitted (no contact visible, wrong shapes, bad values)."""


@dataclass(frozen=True)
class Contact:
    centre_x_px: float
    centre_y_px: float
    radius_px: float
    depth_mm: float | None = None  # the ball's depth, when known or fitted


def changed_region(background: np.ndarray, image: np.ndarray) -> Contact:
    """The weighted centroid of where the colour differs from the background by more than a third
    of its peak, and RADIUS_OF_REGION × that region's equivalent radius."""
    diff = np.abs(cv2.GaussianBlur(image.astype(np.float32) - background.astype(np.float32), (0, 0), 3.0)).sum(axis=2)
    peak = float(diff.max())
    if peak < 15.0:  # three channels of ~5 grey levels: noise and exposure drift, not a press
        raise CalibrationError(f"no contact visible: the frame differs from the background by at most {peak:.1f}")
    mask = (diff > peak / 3).astype(np.uint8)
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(mask)
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    weight = np.where(labels == k, diff, 0.0)
    ys, xs = np.mgrid[0 : diff.shape[0], 0 : diff.shape[1]]
    cx, cy = float((weight * xs).sum() / weight.sum()), float((weight * ys).sum() / weight.sum())
    return Contact(cx, cy, RADIUS_OF_REGION * math.sqrt(stats[k, cv2.CC_STAT_AREA] / math.pi))


def rim_circle(background: np.ndarray, image: np.ndarray, start: Contact, rounds: int = 3) -> Contact | None:
    """The circle through the contact's rim (the steepest radial change of the colour difference
    along RAYS rays from the centre), from ``start``; None when too few rays see a rim."""
    diff = cv2.GaussianBlur(image.astype(np.float32) - background.astype(np.float32), (0, 0), 1.5)
    gx = cv2.Sobel(diff, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(diff, cv2.CV_32F, 0, 1, ksize=3)
    h, w = diff.shape[:2]
    cx, cy, r = start.centre_x_px, start.centre_y_px, start.radius_px / RADIUS_OF_REGION * 0.9
    angles = np.linspace(0, 2 * np.pi, RAYS, endpoint=False)
    cos, sin = np.cos(angles)[:, None], np.sin(angles)[:, None]
    for _ in range(rounds):
        if r < MIN_RIM_PX:
            return None
        radii = np.linspace(0.6 * r, 1.5 * r, 80)[None, :]
        X, Y = cx + cos * radii, cy + sin * radii
        radial = np.zeros(X.shape)
        for ch in range(3):
            along_x = map_coordinates(gx[..., ch], [Y, X], order=1, mode="nearest")
            along_y = map_coordinates(gy[..., ch], [Y, X], order=1, mode="nearest")
            radial += np.abs(along_x * cos + along_y * sin)
        best = radial.argmax(axis=1)
        px, py = X[np.arange(RAYS), best], Y[np.arange(RAYS), best]
        inside = (px > 3) & (px < w - 4) & (py > 3) & (py < h - 4) & (best > 0) & (best < radii.shape[1] - 1)
        if inside.sum() < RAYS // 2:
            return None
        p = np.stack([px[inside], py[inside]], axis=1)
        A = np.c_[2 * p, np.ones(len(p))]
        sol, *_ = np.linalg.lstsq(A, (p**2).sum(axis=1), rcond=None)
        cx, cy = float(sol[0]), float(sol[1])
        r = math.sqrt(max(sol[2] + cx * cx + cy * cy, 0.0))
    return Contact(cx, cy, r)


def find_contact(background: np.ndarray, image: np.ndarray) -> Contact:
    """Centre and radius (px) of a ball press: the rim's circle where the frame shows one within
    half a region radius of the changed region's centroid, else the centroid; the contact radius is
    RIM_TO_CONTACT of the rim's. CalibrationError when the frame shows no contact."""
    region = changed_region(background, image)
    rim = rim_circle(background, image, region)
    if rim is None or math.hypot(rim.centre_x_px - region.centre_x_px, rim.centre_y_px - region.centre_y_px) > (
        0.5 * region.radius_px / RADIUS_OF_REGION
    ):
        return region
    return Contact(rim.centre_x_px, rim.centre_y_px, RIM_TO_CONTACT * rim.radius_px)
