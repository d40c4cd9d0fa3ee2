"""The run browser's condition panel: the object image placed at a frame's measured pose, exactly
as the model sees it (dataset/condition.py, the PyTorch Dataset's own placement), read through the
verified reader (acquisition/run_reader.py). Kept apart from runs.py, whose reads another change
routes; only this panel needs the pose, the object image and mm_per_px together.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from acquisition import schema as S
from common.errors import ToolError


class NoCondition(ToolError):
    """A frame whose condition cannot be shown (no such frame, no object image, no mm per pixel)."""


def condition_at(path: Path, index: int) -> tuple[np.ndarray, dict]:
    """(the condition image of frame ``index`` (BGR uint8, the frame's size), the pose it is placed
    at: x, y (mm), theta (deg), and mm_per_px)."""
    import math

    from acquisition.run_reader import RunReader
    from dataset.condition import condition_image

    with RunReader.open(path) as run:
        if not 0 <= index < run.n:
            raise NoCondition(f"{path.name} has frames 0..{run.n - 1}, not {index}")
        if S.OBJECT_IMAGE not in run.images:
            raise NoCondition(f"{path.name} has no {S.OBJECT_IMAGE}")
        pose = np.asarray(run.rows[S.POSE_MEASURED][index], dtype=np.float64)
        mm_per_px = run.number(S.ATTR_MM_PER_PX)
        image = run.image(S.OBJECT_IMAGE)
        width = run.frame_shape[1]
    if not (math.isfinite(mm_per_px) and mm_per_px > 0):
        raise NoCondition(f"{path.name}: mm_per_px is {mm_per_px}: the object cannot be placed in mm")
    placed = condition_image(image, pose[0], pose[1], pose[3], mm_per_px, width, width)
    return placed, {"x_mm": float(pose[0]), "y_mm": float(pose[1]), "theta_deg": float(pose[3]), "mm_per_px": mm_per_px}
