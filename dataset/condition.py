"""The contact condition: the object image placed at each frame's pose, and the wrench normalised."""

from __future__ import annotations

import cv2
import numpy as np


def background_bgr(image: np.ndarray) -> tuple[float, float, float]:
    """The colour of an image's background: the median of its outermost ring of pixels, per channel.

    An object photo shows the object in its middle and its surroundings at the edges; when it is
    translated or rotated, the uncovered area is filled with this (black for the library's
    rendered objects, grey for a photo on a grey table), never with a colour the photo lacks.
    """
    ring = np.concatenate([image[0], image[-1], image[1:-1, 0], image[1:-1, -1]]).reshape(-1, image.shape[-1])
    b, g, r = (float(v) for v in np.median(ring, axis=0)[:3])
    return (b, g, r)


def place_object(
    object_image: np.ndarray, x_mm: float, y_mm: float, theta_deg: float, mm_per_px: float, size: int | None = None
) -> np.ndarray:
    """The object image translated by (x, y) mm and rotated by θ about its axis.

    The image is the contact face centred at pose (0, 0, 0°); +x is right, +y up
    (image rows run down), the convention of dataset/pose_convention.py. The area the move
    uncovers takes the image's own background colour (``background_bgr``), so no rectangle
    appears around a photo with a non-black background. Returns (size, size, 3) uint8 (size:
    the input's by default).
    """
    h, w = object_image.shape[:2]
    centre = ((w - 1) / 2, (h - 1) / 2)
    M = cv2.getRotationMatrix2D(centre, theta_deg, 1.0)  # counter-clockwise for +θ, as seen by the camera
    M[0, 2] += x_mm / mm_per_px
    M[1, 2] -= y_mm / mm_per_px
    placed = cv2.warpAffine(object_image, M, (w, h), flags=cv2.INTER_LINEAR, borderValue=background_bgr(object_image))
    if size is not None and size != w:
        placed = cv2.resize(placed, (size, size), interpolation=cv2.INTER_AREA)
    return placed


def condition_image(
    object_image: np.ndarray, x_mm: float, y_mm: float, theta_deg: float, mm_per_px: float, frame_px: int, size: int
) -> np.ndarray:
    """The condition image of the model: the object at the pose, (size, size, 3) uint8.

    ``object_image`` spans the sensor's field of view, ``frame_px`` × ``mm_per_px`` mm
    (``mm_per_px`` is the tactile frame's scale at ``frame_px`` pixels across); it is
    brought to ``frame_px`` first, so that training (object images stored at the frame's
    size) and generation (an object image of any size) place the object identically.
    """
    if object_image.shape[0] != object_image.shape[1]:
        raise ValueError(
            f"object image is {object_image.shape[1]}x{object_image.shape[0]} px; expected a square image "
            "of the sensor's field of view"
        )
    if object_image.shape[0] != frame_px:
        object_image = cv2.resize(
            object_image,
            (frame_px, frame_px),
            interpolation=cv2.INTER_AREA if object_image.shape[0] > frame_px else cv2.INTER_LINEAR,
        )
    return place_object(object_image, x_mm, y_mm, theta_deg, mm_per_px, size=size)


def normalise_wrench(wrench: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    return (np.asarray(wrench, dtype=np.float64) - mean) / std
