"""A check sheet of an object file: its photo and its height map side by side at the sensor's scale.

Three panels of the sensor's field of view, centred on the object's axis: the photo as the
model's condition sees it, the height map (brighter = nearer the gel; black: no material),
and the photo with the height map's outline, so a scale or centre that disagrees shows at
a glance. ``rig object check FILE --out sheet.png`` writes it.
"""

from __future__ import annotations

import cv2
import numpy as np

from objects.indenters import FAR_MM
from objects.object_file import ObjectFile

LABEL_PX = 22  # strip above each panel for its title


def height_panel(obj: ObjectFile, size_px: int, mm_per_px: float) -> tuple[np.ndarray, np.ndarray]:
    """(BGR panel of the height map, material mask) over the field; all black without a height map."""
    if obj.height_map is None:
        return np.zeros((size_px, size_px, 3), np.uint8), np.zeros((size_px, size_px), bool)
    coords = (np.arange(size_px) - (size_px - 1) / 2) * mm_per_px
    U, V = np.meshgrid(coords, -coords)  # image rows go down, v goes up
    sep = obj.height_map.separation(U, V)
    present = sep < FAR_MM / 2
    relief = max(obj.height_map.relief_mm, 1e-6)
    grey = np.clip(60 + 195 * (1.0 - sep / relief), 60, 255).astype(np.uint8)  # the lowest material still shows
    panel = cv2.applyColorMap(grey, cv2.COLORMAP_VIRIDIS)
    panel[~present] = 0
    return panel, present


def _titled(panel: np.ndarray, title: str) -> np.ndarray:
    strip = np.full((LABEL_PX, panel.shape[1], 3), 255, np.uint8)
    cv2.putText(strip, title, (4, LABEL_PX - 7), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([strip, panel])


def _cross(panel: np.ndarray) -> np.ndarray:
    """The object's axis (the pose's x, y) marked in the middle of the panel."""
    out = panel.copy()
    c = panel.shape[0] // 2
    cv2.drawMarker(out, (c, c), (0, 0, 255), cv2.MARKER_CROSS, 12, 1)
    return out


def check_sheet(obj: ObjectFile, size_px: int = 256, mm_per_px: float = 14.0 / 256) -> np.ndarray:
    """BGR uint8: photo | height map | photo with the height map's outline, each ``size_px``
    square at ``mm_per_px`` (the sensor's field), titled, the object's axis marked."""
    photo = obj.object_image(size_px, mm_per_px)
    heights, present = height_panel(obj, size_px, mm_per_px)
    overlay = photo.copy()
    if present.any():
        contours, _ = cv2.findContours(present.astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(overlay, contours, -1, (0, 0, 255), 1)
    field_mm = size_px * mm_per_px
    hm = obj.height_map
    panels = [
        _titled(_cross(photo), f"photo, {field_mm:.1f} mm across"),
        _titled(
            _cross(heights),
            f"height map, relief {hm.relief_mm:.2f} mm" if hm is not None else "no height map: real rig only",
        ),
        _titled(_cross(overlay), "photo + height map outline"),
    ]
    gap = np.full((size_px + LABEL_PX, 4, 3), 255, np.uint8)
    return np.hstack([panels[0], gap, panels[1], gap, panels[2]])


def describe(obj: ObjectFile, size_px: int = 256, mm_per_px: float = 14.0 / 256) -> list[str]:
    """The sizes a person checks against a ruler: each image in pixels and mm, the axis, the relief."""
    h, w = obj.photo_bgr.shape[:2]
    s = obj.photo_mm_per_px
    cx, cy = obj.photo_centre_px
    lines = [
        f"object {obj.name!r}: {obj.description}",
        f"photo: {w}x{h} px at {s:g} mm/px = {w * s:.2f} x {h * s:.2f} mm; axis at ({cx:g}, {cy:g}) px; "
        f"sha256 {obj.photo_sha256[:12]}",
    ]
    hm = obj.height_map
    if hm is None:
        lines.append("height map: none (the simulated rig refuses this object; the real rig runs it)")
    else:
        hh, hw = hm.height_mm.shape
        m = hm.mm_per_px
        lines.append(
            f"height map: {hw}x{hh} px at {m:g} mm/px = {hw * m:.2f} x {hh * m:.2f} mm; axis at "
            f"({hm.centre_px[0]:g}, {hm.centre_px[1]:g}) px; relief {hm.relief_mm:.3f} mm; "
            f"face radius {hm.radius_mm:.2f} mm"
        )
    lines.append(f"panels: {size_px} px at {mm_per_px:g} mm/px = {size_px * mm_per_px:.2f} mm (the sensor's field)")
    return lines
