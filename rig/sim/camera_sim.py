"""The simulated tactile camera: frames rendered from the world at ``fps`` on the clock.

Each frame solves the contact at the world's current pose (sharing the gauge's solve
when the pose has not moved) and renders it with the sensor's optics. A world whose
contact model has no fields (the spring placeholder) shows the no-contact frame.
"""

from __future__ import annotations

from rig.clock import Clock
from sensor_sim.light import OpticsSpec
from sensor_sim.optics import Renderer
from rig.sim.world import SimWorld


class SimCameraSource:
    """A capture source (``read``/``release``) producing frames at ``fps`` of clock time."""

    def __init__(self, world: SimWorld, clock: Clock, *, fps: float = 25.0, height: int = 256, width: int = 256,
                 kind: str = "rgb", noise_std: float = 1.0, seed: int = 0, triggered: bool = False):
        if height != width:
            raise ValueError(f"the simulated camera renders a square gel pad: width ({width}) must equal height ({height})")
        self.world = world
        self.clock = clock
        self.period_s = 1.0 / fps
        solver = getattr(world.contact, "solver", None)
        geometry = solver.geometry if solver is not None else None
        self.renderer = Renderer(OpticsSpec(kind=kind, height_px=height, width_px=width, noise_std=noise_std),
                                 geometry, seed=seed)
        self._next_t: float | None = None
        self._released = False
        self.triggered = triggered  # render only when the Camera is triggered (acquisition)
        self.last_exposure_s: float | None = None

    def render_now(self):
        self.last_exposure_s = self.clock.now()
        contact = self.world.contact
        if not hasattr(contact, "solve"):
            return self.renderer.render({})
        result = contact.solve(self.world.pose(), self.renderer.needs())
        return self.renderer.render(result.fields)

    def read(self):
        if self._released:
            return False, None
        if self.triggered:
            return True, self.render_now()
        now = self.clock.now()
        if self._next_t is None:
            self._next_t = now
        self.clock.sleep(self._next_t - now)
        self._next_t += self.period_s
        return True, self.render_now()

    def release(self) -> None:
        self._released = True
