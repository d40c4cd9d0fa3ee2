"""An object pressed into a sensor at a pose, rendered at the sensor's resolution: the one render call.

    frame = render_press(profile, "sphere4mm", Pose(1.0, -2.0, -0.8, 0.0))   # BGR uint8, H × W
    press = PressRender(profile, "sphere4mm", kind="rgb_markers", noise=True, seed=3)
    press.render(pose, wrench)     # the frame; for markers the tangential state carrying Fx, Fy, Mz
    press.solve(pose)              # the contact (wrench, pressure, fields) behind it
    press.sink_mm(pose)            # the gel's sink on the frame's pixels (mm, into the gel)

The contact solver and the renderer are the simulated rig's own: ``rig_contact`` on the
profile's gel and pad (its cells: ``rig_cells``; its tolerance: RIG_TOL) and ``Renderer``
with the profile's optics, background and noise, at the profile's frame (or another frame
size and scale: a run's). Poses are the rig's: x, y (mm from the frame's centre, +y towards
the frame's top), z (mm, negative pressed in), θ (deg). Every render call of the project goes
through here: ``rig sensor render``, the calibration's fit and contact sheet, the physics row
of ``evaluate`` and the physics conditioning (model/conditioning/baseline.py's ``ObjectRender``).

Each render is of the pose alone, without the friction history of a run (the simulated rig
keeps one); for a marker sensor a measured wrench stands in for it (sensor_sim/load_match.py).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from objects.indenters import Indenter, get_indenter
from objects.object_file import is_object_file, load_object_file
from objects.pose import Pose
from sensor_sim.contact import ContactResult, SensorGeometry
from sensor_sim.optics import Renderer
from sensor_sim.world_contact import rig_cells, rig_contact


def indenter_of(obj: Indenter | str) -> Indenter:
    """A library object's name, an object file (.toml with a height map) or an Indenter."""
    if isinstance(obj, Indenter):
        return obj
    if is_object_file(obj):
        return load_object_file(obj).indenter()  # NoHeightMap (one line) when it has none
    return get_indenter(obj)  # KeyError naming the known objects


class PressRender:
    """``obj`` pressed into the sensor of ``profile``, rendered for sensor ``kind``.

    ``frame_px`` (width, height) and ``mm_per_px``: another frame than the profile's (a run's);
    ``background``: another no-contact frame (BGR, any size of the frame's aspect); ``noise``: the
    profile's camera noise (off by default: a render of the physics, not of one exposure)."""

    def __init__(
        self,
        profile,
        obj: Indenter | str,
        kind: str = "rgb",
        *,
        noise: bool = False,
        seed: int = 0,
        frame_px: tuple[int, int] | None = None,
        mm_per_px: float | None = None,
        background: np.ndarray | None = None,
    ):
        self.profile = profile
        self.indenter = indenter_of(obj)
        w, h = frame_px if frame_px is not None else (profile.width_px, profile.height_px)
        scale = mm_per_px if mm_per_px is not None else profile.mm_per_px * profile.width_px / w
        width_mm, height_mm = w * scale, h * scale
        self.geometry = SensorGeometry(width_mm=width_mm, height_mm=height_mm, cells=rig_cells(width_mm, height_mm))
        self.contact = rig_contact(self.indenter, profile.gel(), self.geometry)
        self.geometry = self.contact.solver.geometry  # refined for a small object
        spec = dataclasses.replace(profile.optics_spec(kind), width_px=w, height_px=h)
        if not noise:
            spec = dataclasses.replace(spec, noise_std=0.0, noise=None)
        self.renderer = Renderer(spec, self.geometry, background, seed, profile=profile)

    @property
    def frame_shape(self) -> tuple[int, int]:
        return self.renderer.spec.height_px, self.renderer.spec.width_px

    def pose_of_pixel(self, col: float, row: float, z_mm: float, theta_deg: float = 0.0) -> Pose:
        """The pose whose axis is at frame pixel (col, row)."""
        h, w = self.frame_shape
        mm = self.renderer.mm_per_px
        return Pose((col - (w - 1) / 2) * mm, ((h - 1) / 2 - row) * mm, z_mm, theta_deg)

    def solve(self, pose: Pose, wrench=None, fields=None) -> ContactResult:
        """The contact at ``pose`` (no friction history), with the fields the sensor needs (or
        ``fields``); ``wrench`` (Fx, Fy, Fz N, Mx, My, Mz N·mm): for a marker sensor, the
        tangential state that carries its Fx, Fy and Mz."""
        from sensor_sim.load_match import contact_at_load

        finite_pose(pose)
        if wrench is not None:
            finite_values("wrench (Fx, Fy, Fz N, Mx, My, Mz N·mm)", wrench, 6)
        self.contact.reset()
        needs = self.renderer.needs() if fields is None else frozenset(fields)
        if wrench is None or "uxy" not in needs:
            return self.contact.solve(pose, needs)
        w = np.asarray(wrench, dtype=float).reshape(6)
        return contact_at_load(self.contact.solver, pose, (w[0], w[1], w[5]), needs).result

    def render(self, pose: Pose, wrench=None) -> np.ndarray:
        """The BGR uint8 frame (H, W, 3) of the object at ``pose`` (see ``solve`` for ``wrench``)."""
        return self.renderer.render(self.solve(pose, wrench).fields)

    def sink_mm(self, pose: Pose) -> np.ndarray:
        """(H, W) float32: the gel's sink at ``pose`` on the frame's pixels, as the renderer samples it."""
        return self.renderer.sink_on_frame(self.solve(pose, fields={"uz"}).fields["uz"])

    def pose_at_force(self, x_mm: float, y_mm: float, theta_deg: float, fz_N: float) -> np.ndarray:
        """(x, y, z, θ) with z the depth at which the object there presses with ``fz_N`` (the
        simulator's own force-depth relation; ValueError for a force it cannot give)."""
        from sensor_sim.load_match import depth_for_force

        finite_values("x_mm, y_mm, theta_deg, fz_N", (x_mm, y_mm, theta_deg, fz_N), 4)
        depth = depth_for_force(self.contact.solver, x_mm, y_mm, theta_deg, fz_N)
        return np.array([x_mm, y_mm, -depth, theta_deg])


def render_press(profile, obj: Indenter | str, pose: Pose, *, wrench=None, kind: str = "rgb", noise=True, seed=0):
    """The frame (BGR uint8, the profile's size) of ``obj`` at ``pose`` through ``profile``."""
    return PressRender(profile, obj, kind, noise=noise, seed=seed).render(pose, wrench)


def finite_pose(pose: Pose) -> None:
    """ValueError in one line unless the pose's four numbers are finite."""
    finite_values("pose (x_mm, y_mm, z_mm, theta_deg)", (pose.x_mm, pose.y_mm, pose.z_mm, pose.theta_deg), 4)


def finite_values(name: str, values, count: int) -> None:
    """ValueError in one line naming ``name`` unless ``values`` are ``count`` finite numbers."""
    try:
        arr = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {count} numbers, got {values!r}") from None
    if arr.size != count or not np.isfinite(arr).all():
        shown = ", ".join(f"{v:g}" for v in arr)
        raise ValueError(f"{name}: expected {count} finite numbers, got ({shown})")
