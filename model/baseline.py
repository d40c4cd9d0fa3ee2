"""The lighting-model baseline row: the simulator's own physics render of each test frame.

For a frame it takes what a physics simulator is given (the object and its measured
pose x, y, z, θ), solves the gel's contact mechanics the simulated rig solves
(sensor_sim.world_contact.rig_contact) and lights the result with the calibrated optics
(sensor_sim.optics), with no sensor noise. Each frame is rendered on its own,
without the friction history of the frames before it, as Taxim or FOTS render one.

Background: the run's own no-contact reference frame for sensors without markers (so
on real data the row measures the lighting and mechanics, not the sensor's shading);
the simulator's background for marker sensors, whose reference frame holds markers
at rest that the render draws itself.
"""

from __future__ import annotations

import time

import cv2
import h5py
import numpy as np

from acquisition import schema as S


class BaselineUnavailable(ValueError):
    pass


class PhysicsRender:
    def __init__(self, run_path: str, *, noise_std: float = 0.0):
        from objects.indenters import INDENTERS
        from sensor_sim.light import OpticsSpec
        from sensor_sim.optics import Renderer
        from sensor_sim.world_contact import rig_contact

        with h5py.File(run_path, "r", swmr=True) as f:
            attrs = dict(f.attrs)
            obj = str(attrs.get(S.ATTR_OBJECT, ""))
            kind = str(attrs.get(S.ATTR_SENSOR_KIND, "rgb"))
            h, w = f[S.FRAMES].shape[1:3]
            reference = f[S.REFERENCE_FRAME][()]
        if obj not in INDENTERS:
            raise BaselineUnavailable(
                f"{run_path}: object {obj!r} is not one the simulator knows ({', '.join(INDENTERS)}): no physics render"
            )
        if h != w:
            raise BaselineUnavailable(f"{run_path}: frames are {w}x{h}; the simulator renders a square pad")
        self.contact = rig_contact(obj)
        spec = OpticsSpec(kind=kind, height_px=h, width_px=w, noise_std=noise_std)
        background = None if spec.has_markers else reference
        self.renderer = Renderer(spec, self.contact.solver.geometry, background)

    def render(self, pose_measured: np.ndarray) -> np.ndarray:
        """BGR uint8 frame at the run's size for a pose (x, y, z mm from the contact point, θ deg)."""
        from objects.pose import Pose

        self.contact.reset()  # the pose alone: no friction history
        x, y, z, theta = (float(v) for v in pose_measured)
        result = self.contact.solve(Pose(x, y, z, theta), self.renderer.needs())
        return self.renderer.render(result.fields)


def render_frames(
    run_paths: list[str], rows: np.ndarray, poses: np.ndarray, size: int
) -> tuple[list[np.ndarray], float]:
    """Physics renders of (run, frame) ``rows`` at their poses, resized to ``size`` as the
    dataset resizes real frames; and the seconds per frame it took."""
    renderers: dict[int, PhysicsRender] = {}
    out = []
    t0 = time.perf_counter()
    for (run, _), pose in zip(rows, poses):
        run = int(run)
        if run not in renderers:
            renderers[run] = PhysicsRender(run_paths[run])
        img = renderers[run].render(pose)
        if img.shape[0] != size:
            img = cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)
        out.append(img)
    return out, (time.perf_counter() - t0) / max(1, len(out))
