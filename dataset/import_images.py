"""Imported images made square, or refused: frames, the reference frame and the object image.

The model trains on square images (a non-square frame would be squashed square, and its one
mm-per-pixel scale would then be wrong along one axis), and the condition is the object image
brought to the frame's size. So an import says what to do with a non-square image:

- ``crop``: the centre square (side: the shorter side); the scale is unchanged;
- ``pad``: the centre of a square (side: the longer side), filled with the image's own edge
  colour (its median border, as the condition's background); the scale is unchanged;
- ``size``: after the crop or pad, resize to ``size_px`` × ``size_px`` (the scale grows by
  side / size_px); alone it resizes square images only (it would stretch a non-square one).

The centre stays the centre, so poses (relative to the contact point at the frame's centre)
keep their meaning.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from acquisition.run_file import RunFileError
from dataset.condition import background_bgr

SHAPES = ("crop", "pad")
SIZE_PX = (16, 4096)  # the smallest image the model's U-Net takes, up to a 4K camera


class ImageShapeError(RunFileError):
    """An imported image that is not square (or has another aspect than the frames) and no option says what to do."""


@dataclass(frozen=True)
class Squaring:
    """How an import makes its images square: ``shape`` one of SHAPES or None, ``size_px`` or None."""

    shape: str | None = None
    size_px: int | None = None

    def options(self) -> str:
        words = [f"--{self.shape}"] if self.shape else []
        return " ".join(words + ([f"--size {self.size_px}"] if self.size_px else [])) or "none"


def read_image(path: Path, what: str) -> np.ndarray:
    if path.exists() and not path.is_file():  # a named pipe would block the read for ever
        raise RunFileError(f"{path}: {what} is not a regular file (expected a PNG or JPEG image)")
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise RunFileError(f"{path}: cannot read {what} (expected a PNG or JPEG image)")
    return img


def check_square(path: Path, img: np.ndarray, what: str, squaring: Squaring) -> None:
    """Refuse a non-square image unless ``--crop`` or ``--pad`` says what to do, naming both and why."""
    h, w = img.shape[:2]
    if h == w or squaring.shape is not None:
        return
    side_lo, side_hi = min(h, w), max(h, w)
    stretch = "" if squaring.size_px is None else f" (--size {squaring.size_px} alone would stretch it {w / h:.2f}:1)"
    raise ImageShapeError(
        f"{path}: {what} is {w}x{h}, not square{stretch}; the model trains on square images and would squash "
        f"it, making its mm per pixel wrong along one axis: pass --crop (the centre {side_lo}x{side_lo}) or "
        f"--pad (centred in {side_hi}x{side_hi}, filled with its edge colour), and --size N to resize"
    )


def square(img: np.ndarray, squaring: Squaring) -> np.ndarray:
    """The image made square by ``squaring.shape`` (centre kept), then resized to ``size_px``."""
    h, w = img.shape[:2]
    if h != w and squaring.shape == "crop":
        side = min(h, w)
        top, left = (h - side) // 2, (w - side) // 2
        img = img[top : top + side, left : left + side]
    elif h != w and squaring.shape == "pad":
        side = max(h, w)
        top, left = (side - h) // 2, (side - w) // 2
        fill = background_bgr(img)
        img = cv2.copyMakeBorder(img, top, side - h - top, left, side - w - left, cv2.BORDER_CONSTANT, value=fill)
    if squaring.size_px is not None and img.shape[0] != squaring.size_px:
        shrink = img.shape[0] > squaring.size_px
        img = cv2.resize(
            img,
            (squaring.size_px, squaring.size_px),
            interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR,
        )
    return np.ascontiguousarray(img)


def squared_mm_per_px(mm_per_px: float, frame_shape: tuple[int, ...], squaring: Squaring) -> float:
    """The frames' scale after ``square``: unchanged by a crop or pad, times side / size_px by --size."""
    h, w = frame_shape[:2]
    side = w if h == w else (min(h, w) if squaring.shape == "crop" else max(h, w))
    return mm_per_px * side / squaring.size_px if squaring.size_px else mm_per_px
