"""A contact sheet of a run: evenly spaced frames labelled with their wrenches and poses.

With ``condition=True`` each tile also shows the contact condition the model is given (the
run's object image placed at the frame's measured pose, dataset/condition.py) as a tinted
area with its outline, its centroid (o) beside the centroid of what changed in the frame
against the reference frame (+). On a sound run the two marks sit together; a mirrored pose
axis, a wrong mm per pixel or a shifted origin pulls them apart, and ``Sheet.offsets_px``
measures by how much.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader
from acquisition.writer_lock import RunFileError
from common.wording import signed
from dataset.condition import background_bgr, place_object

COLS = 6
CONDITION_BGR = (255, 0, 255)  # magenta: the condition (object at the pose)
CONTACT_BGR = (255, 255, 0)  # cyan: the contact seen in the frame
TINT = 0.35  # opacity of the condition's area over the frame
OBJECT_LEVELS = 30  # summed |BGR - background| above which an object-image pixel is the object
CONTACT_CHANGE = 0.3  # summed relative change below which nothing touched (noise alone: ~0.06 at 1 grey level)
CONTACT_FRACTION = 0.2  # of the peak change: the contact's extent (1 px from the true centre on simulated presses)
DARK_LEVELS = 16.0  # grey levels added to the reference so dark pixels' noise does not count as change
LEGEND_PX = 22


@dataclass(frozen=True)
class Tile:
    """One frame of the sheet: its pose and wrench, and (with the condition) both centroids in frame pixels (x, y)."""

    frame: int
    pose: np.ndarray  # x_mm, y_mm, z_mm, theta_deg (measured)
    wrench: np.ndarray  # Fx Fy Fz [N], Mx My Mz [N·mm]
    condition_px: tuple[float, float] | None = None  # centroid of the placed object; None: out of view
    contact_px: tuple[float, float] | None = None  # centroid of the change from the reference; None: no contact

    @property
    def offset_px(self) -> float | None:
        if self.condition_px is None or self.contact_px is None:
            return None
        return float(np.hypot(self.condition_px[0] - self.contact_px[0], self.condition_px[1] - self.contact_px[1]))


@dataclass
class Sheet:
    tiles: list[Tile] = field(default_factory=list)
    frame_px: int = 0  # the frames' width

    @property
    def offsets_px(self) -> list[float]:
        """Condition-to-contact distances of the tiles where both are seen, frame pixels."""
        return [d for d in (t.offset_px for t in self.tiles) if d is not None]

    @property
    def median_offset_px(self) -> float | None:
        return float(np.median(self.offsets_px)) if self.offsets_px else None


def _centroid(weight: np.ndarray) -> tuple[float, float] | None:
    total = float(weight.sum())
    if total <= 0:
        return None
    ys, xs = np.indices(weight.shape)
    return (float((xs * weight).sum()) / total, float((ys * weight).sum()) / total)


def contact_centroid_px(frame: np.ndarray, reference: np.ndarray) -> tuple[float, float] | None:
    """Where the frame differs from the reference: the centroid of the relative change above a
    fifth of its peak (blurred, so single noisy pixels do not count); None when nothing changed
    beyond noise. Relative, because the gel's light is brighter on one side of the frame than the
    other, and an absolute change would pull the centroid towards the brighter side (by ~10 px on
    simulated 256 px frames, ~1 px relative)."""
    if frame.shape != reference.shape:
        reference = cv2.resize(reference, frame.shape[1::-1], interpolation=cv2.INTER_AREA)
    ref = reference.astype(np.float32)
    change = (np.abs(frame.astype(np.float32) - ref) / (ref + DARK_LEVELS)).sum(axis=2)
    change = cv2.GaussianBlur(change, (0, 0), 1.5)
    peak = float(change.max())
    if peak < CONTACT_CHANGE:
        return None
    return _centroid(np.clip(change - CONTACT_FRACTION * peak, 0, None))


def object_mask(placed: np.ndarray, background: tuple[float, float, float]) -> np.ndarray:
    """Pixels of a placed object image that differ from its background: the object (float 0/1)."""
    diff = np.abs(placed.astype(np.float32) - np.asarray(background, np.float32)).sum(axis=2)
    return (diff > OBJECT_LEVELS).astype(np.float32)


@functools.lru_cache(maxsize=1)
def _font():
    """matplotlib's DejaVu Sans at 11 px: it has · θ °, which OpenCV's Hershey fonts lack ("Nmm")."""
    from matplotlib import font_manager
    from PIL import ImageFont

    return ImageFont.truetype(font_manager.findfont("DejaVu Sans"), 11)


def _label(img: np.ndarray, lines: list[str], top_px: int = 0) -> None:
    """White text with a dark halo, 13 px a line, drawn into ``img`` (BGR) in place."""
    from PIL import Image, ImageDraw

    pil = Image.fromarray(np.ascontiguousarray(img[:, :, ::-1]))
    draw = ImageDraw.Draw(pil)
    for row, text in enumerate(lines):
        at = (4, top_px + 2 + 13 * row)
        draw.text(at, text, fill=(255, 255, 255), font=_font(), stroke_width=2, stroke_fill=(0, 0, 0))
    img[:] = np.asarray(pil)[:, :, ::-1]


def _overlay(img: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The condition's area tinted and outlined on a tile (mask at the tile's size)."""
    inside = mask > 0.5
    tinted = img.astype(np.float32)
    tinted[inside] = (1 - TINT) * tinted[inside] + TINT * np.asarray(CONDITION_BGR, np.float32)
    out = tinted.astype(np.uint8)
    contours, _ = cv2.findContours(inside.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    cv2.drawContours(out, contours, -1, CONDITION_BGR, 1, cv2.LINE_AA)
    return out


def _mark(img: np.ndarray, point: tuple[float, float] | None, scale: float, contact: bool) -> None:
    if point is None:
        return
    at = (int(round(point[0] * scale)), int(round(point[1] * scale)))
    if contact:
        cv2.drawMarker(img, at, CONTACT_BGR, cv2.MARKER_CROSS, 11, 2)
    else:
        cv2.circle(img, at, 5, CONDITION_BGR, 2, cv2.LINE_AA)


def contact_sheet(
    path: str | Path, out: str | Path, *, tiles: int = 24, tile_px: int = 160, condition: bool = False
) -> Sheet:
    """Write the sheet PNG; the tiles with their poses, wrenches and (with ``condition``) centroids."""
    sheet = Sheet()
    images = []
    with RunReader.open(path) as run:
        n = run.n
        if n == 0:
            raise RunFileError(f"{path}: no frames to preview")
        sheet.frame_px = int(run.frame_shape[1])
        obj = run.image(S.OBJECT_IMAGE) if condition else None
        reference = run.image(S.REFERENCE_FRAME) if condition else None
        mm_per_px = run.number(S.ATTR_MM_PER_PX)
        if condition and not np.isfinite(mm_per_px):
            raise RunFileError(f"{path}: attribute {S.ATTR_MM_PER_PX} is {mm_per_px}: the condition cannot be placed")
        picks = np.unique(np.linspace(0, n - 1, min(tiles, n)).astype(int))
        for i in picks:
            frame = run.frame(int(i))
            w = run.rows[S.WRENCH][int(i)]
            pose = run.rows[S.POSE_MEASURED][int(i)]
            img = cv2.resize(frame, (tile_px, tile_px), interpolation=cv2.INTER_AREA)
            lines = [
                f"#{i}",
                f"F {signed(w[0], 2)} {signed(w[1], 2)} {signed(w[2], 2)} N",
                f"M {signed(w[3], 0)} {signed(w[4], 0)} {signed(w[5], 1)} N·mm",
            ]
            bottom = [
                f"x {signed(pose[0], 2)} y {signed(pose[1], 2)} z {signed(pose[2], 2)} mm",
                f"θ {signed(pose[3], 1)}°",
            ]
            tile = Tile(int(i), pose, w)
            if obj is not None and reference is not None:
                if obj.shape[:2] != frame.shape[:2]:
                    obj = cv2.resize(obj, frame.shape[1::-1], interpolation=cv2.INTER_AREA)
                placed = place_object(obj, float(pose[0]), float(pose[1]), float(pose[3]), mm_per_px)
                mask = object_mask(placed, background_bgr(obj))
                tile = Tile(int(i), pose, w, _centroid(mask), contact_centroid_px(frame, reference))
                img = _overlay(img, cv2.resize(mask, (tile_px, tile_px), interpolation=cv2.INTER_AREA))
                scale = tile_px / frame.shape[1]
                _mark(img, tile.condition_px, scale, contact=False)
                _mark(img, tile.contact_px, scale, contact=True)
                bottom[1] += "  offset " + ("-" if tile.offset_px is None else f"{tile.offset_px:.1f} px")
            _label(img, lines)
            _label(img, bottom, top_px=tile_px - 2 * 13 - 4)
            sheet.tiles.append(tile)
            images.append(img)
    while len(images) % COLS:
        images.append(np.zeros_like(images[0]))
    grid = np.vstack([np.hstack(images[r : r + COLS]) for r in range(0, len(images), COLS)])
    if condition:
        grid = np.vstack([grid, _legend(grid.shape[1], sheet)])
    out = Path(out)
    try:
        encoded, data = cv2.imencode(out.suffix or ".png", grid)
    except cv2.error:
        encoded = False
    if not encoded:
        raise RunFileError(
            f"--out {out}: cannot encode a contact sheet as {out.suffix or 'nothing'!r}; expected a .png path"
        )
    try:
        out.write_bytes(data.tobytes())
    except OSError as exc:
        raise RunFileError(f"--out {out}: cannot write the contact sheet ({exc.strerror or exc})") from None
    return sheet


def _legend(width_px: int, sheet: Sheet) -> np.ndarray:
    strip = np.zeros((LEGEND_PX, width_px, 3), np.uint8)
    median = sheet.median_offset_px
    text = "magenta o: condition (object at the pose)   cyan +: contact seen in the frame   median offset " + (
        "-" if median is None else f"{median:.1f} px of {sheet.frame_px}"
    )
    cv2.putText(strip, text, (4, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
    return strip


def preview(path: str | Path, out: str | Path, *, tiles: int = 24, tile_px: int = 160) -> int:
    """A contact sheet of evenly spaced frames, each labelled with its frame index, wrench and pose."""
    return len(contact_sheet(path, out, tiles=tiles, tile_px=tile_px).tiles)
