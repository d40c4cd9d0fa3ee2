"""The simulated tactile camera: frames rendered from the world at ``fps`` on the clock.

Until the optical model lands (issue 3) the render is a placeholder: a smooth
lit-gel background with a shaded disc where the indenter presses, sized by the
Hertz contact radius of a 5 mm-radius sphere. It moves and grows with the pose, so
the pipeline sees frames that change with contact.
"""

from __future__ import annotations

import math

import numpy as np

from rig.clock import Clock
from rig.sim.contact import Pose
from rig.sim.world import SimWorld


def render_placeholder(pose: Pose, height: int, width: int, mm_per_px: float, radius_mm: float = 5.0) -> np.ndarray:
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    cy, cx = (height - 1) / 2, (width - 1) / 2
    r2 = ((yy - cy) ** 2 + (xx - cx) ** 2) / (0.5 * max(height, width)) ** 2
    base = np.stack([150 - 20 * r2, 140 - 15 * r2, 130 - 25 * r2], axis=-1)  # BGR, vignetted
    d = pose.depth_mm
    if d > 0:
        a_px = math.sqrt(radius_mm * d) / mm_per_px
        px = cx + pose.x_mm / mm_per_px
        py = cy - pose.y_mm / mm_per_px
        rr = np.sqrt((yy - py) ** 2 + (xx - px) ** 2) / max(a_px, 1e-6)
        shade = np.clip(1 - rr**2, 0, 1)[..., None]
        gx = ((xx - px) / max(a_px, 1e-6))[..., None]
        base = base + shade * (40 * d) * np.concatenate([1 + gx, 1 - gx, np.ones_like(gx)], axis=-1)
    return np.clip(base, 0, 255).astype(np.uint8)


class SimCameraSource:
    """A capture source (``read``/``release``) producing frames at ``fps`` of clock time."""

    def __init__(self, world: SimWorld, clock: Clock, *, fps: float = 25.0, height: int = 240, width: int = 320,
                 mm_per_px: float = 0.0634):
        self.world = world
        self.clock = clock
        self.period_s = 1.0 / fps
        self.height, self.width, self.mm_per_px = height, width, mm_per_px
        self._next_t: float | None = None
        self._released = False

    def read(self):
        if self._released:
            return False, None
        now = self.clock.now()
        if self._next_t is None:
            self._next_t = now
        self.clock.sleep(self._next_t - now)
        self._next_t += self.period_s
        return True, render_placeholder(self.world.pose(), self.height, self.width, self.mm_per_px)

    def release(self) -> None:
        self._released = True
