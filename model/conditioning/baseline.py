"""The lighting-model baseline row: the simulator's own physics render of each test frame.

For a frame it takes what a physics simulator is given (the object, its measured
pose x, y, z, θ and, for marker sensors, the measured wrench), solves the gel's contact
mechanics the simulated rig solves (sensor_sim.world_contact) and lights the result with a sensor profile's calibrated
optics (sensor_sim.optics), with no sensor noise.

The profile: the one given (``evaluate --profile``), else the one the run file records
(``sensor_profile``, found again by its content hash). A run that records none (a real sensor's
run, or one imported without ``--profile``) is never rendered through another sensor's profile:
``NoProfile`` says so and asks for ``--profile``. The gel (thickness, modulus) is the profile's;
the field of view is the run's (frame width × its mm_per_px) when the file has a scale, else the
profile's. Each frame is rendered on its own,
without the friction history of the frames before it, as Taxim or FOTS render one; for marker
sensors the measured Fx, Fy and Mz stand in for that history (the tangential state that carries
them, sensor_sim/load_match.py), since the markers' shear is what they show.

Background: the run's own no-contact reference frame for sensors without markers (so
on real data the row measures the lighting and mechanics, not the sensor's shading);
the simulator's background for marker sensors, whose reference frame holds markers
at rest that the render draws itself.
"""

from __future__ import annotations

import math
import time

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader
from common.sensors import has_markers


class BaselineUnavailable(ValueError):
    pass


class NoProfile(BaselineUnavailable):
    """A physics render asked for a run that records no sensor profile, and none was given."""


def no_profile(run_path: str, what: str, option: str = "--profile FILE") -> NoProfile:
    return NoProfile(
        f"{run_path}: records no sensor profile (a real sensor's run, or imported without --profile), so {what} "
        f"would render it through another sensor's: pass {option} (rig sensor calibrate writes one)"
    )


def run_profile(run_path: str, record: str, profile=None):
    """The SensorProfile for a run's physics render (see the module docstring): ``profile`` when
    given, else the one ``record`` (the run's ``sensor_profile`` attribute) names. NoProfile when
    the run records none; BaselineUnavailable when it records one that cannot be found again."""
    from sensor_sim.profile import ProfileError, profile_from_record

    if profile is not None:
        return profile
    if not record.strip():
        raise no_profile(run_path, "the physics render")
    try:
        return profile_from_record(record, where=str(run_path))
    except ProfileError as exc:
        raise BaselineUnavailable(str(exc)) from None


def profile_source(run_path: str, record: str, profile=None) -> str:
    """Which profile renders a run, in words (the report names it for each run)."""
    chosen = run_profile(run_path, record, profile)
    how = "given by --profile" if profile is not None else "recorded in the run"
    return f"{chosen.name} (sha256 {chosen.content_hash()[:12]}…, {chosen.path}; {how})"


class ObjectRender:
    """The physics render of a library object on a pad of ``frame_px`` pixels (one number: square;
    (width, height): any frame) at ``mm_per_px`` (None: the profile's own field of view), lit with
    ``profile``'s optics for sensor ``kind``, over ``background`` (BGR, the frame's aspect; None:
    the simulator's own), with the profile's camera noise when ``noise``. The render is
    ``sensor_sim.press_render.PressRender``: the simulated rig's contact solver and renderer, the
    one render function of the project."""

    def __init__(
        self,
        obj: str,
        kind: str,
        profile,
        frame_px: int | tuple[int, int],
        mm_per_px: float | None,
        *,
        background: np.ndarray | None = None,
        noise: bool = False,
        where: str = "",
    ):
        from objects.indenters import INDENTERS
        from sensor_sim.press_render import PressRender

        if obj not in INDENTERS:
            raise BaselineUnavailable(
                f"{where or 'object'}: object {obj!r} is not one the simulator knows ({', '.join(INDENTERS)}): "
                "no physics render"
            )
        self.profile = profile
        size = (frame_px, frame_px) if isinstance(frame_px, int) else tuple(frame_px)
        scale = mm_per_px if mm_per_px is not None and math.isfinite(mm_per_px) and mm_per_px > 0 else None
        if scale is None:  # the profile's own field of view at this frame size
            scale = profile.width_mm / size[0]
        self.press = PressRender(
            profile,
            obj,
            kind,
            noise=noise,
            frame_px=(int(size[0]), int(size[1])),
            mm_per_px=scale,
            background=None if has_markers(kind) else background,
        )
        self.contact = self.press.contact
        self.renderer = self.press.renderer

    def render(self, pose_measured, wrench=None) -> np.ndarray:
        """BGR uint8 frame for a pose (x, y, z mm from the contact point, θ deg) and, for a marker
        sensor, the measured wrench (Fx, Fy, Fz N, Mx, My, Mz N·mm): the gel's tangential state is
        the one that carries the wrench's Fx, Fy and Mz (sensor_sim/load_match.py), which is what
        moves the markers. Without a wrench, the pose alone: the markers as if the indenter had
        pressed straight in."""
        from objects.pose import Pose

        x, y, z, theta = (float(v) for v in pose_measured)
        return self.press.render(Pose(x, y, z, theta), wrench)

    def pose_at_force(self, x_mm: float, y_mm: float, theta_deg: float, fz_N: float) -> np.ndarray:
        """(x, y, z, θ) with z the depth at which the object there presses with ``fz_N`` (the
        simulator's own force-depth relation; ValueError for a force it cannot give)."""
        return self.press.pose_at_force(x_mm, y_mm, theta_deg, fz_N)


class PhysicsRender(ObjectRender):
    def __init__(self, run_path: str, *, noise: bool = False, profile=None, background: str = "run"):
        """A run's object, sensor and scale (see the module docstring). ``profile``: a SensorProfile
        to render with (default: the run's). ``background``: "run" (its no-contact reference frame,
        for sensors without markers) or "simulator" (the simulator's own: what the physics
        conditioning renders on, so that `generate` can render it without the run file)."""
        with RunReader.open(run_path) as run:
            obj = run.text(S.ATTR_OBJECT)
            kind = run.text(S.ATTR_SENSOR_KIND)
            h, w = run.frame_shape[:2]
            reference = run.image(S.REFERENCE_FRAME) if background == "run" else None
            mm_per_px = run.number(S.ATTR_MM_PER_PX)
            record = run.sensor_profile
            self.wrench = run.rows[S.WRENCH]  # every frame's recorded wrench (N, N·mm)
        super().__init__(
            obj,
            kind,
            run_profile(run_path, record, profile),
            (w, h),
            mm_per_px if math.isfinite(mm_per_px) and mm_per_px > 0 else None,
            background=reference,
            noise=noise,
            where=run_path,
        )


def render_frames(
    run_paths: list[str], rows: np.ndarray, poses: np.ndarray, size: int, profile=None, wrenches=None
) -> tuple[list[np.ndarray], float]:
    """Physics renders of (run, frame) ``rows`` at their poses (and ``wrenches``, raw N and N·mm:
    default each frame's recorded one), resized to ``size`` as the dataset resizes real frames;
    and the seconds per frame it took. ``profile``: a SensorProfile for every run (default: each
    run's own, see the module docstring)."""
    renderers: dict[int, PhysicsRender] = {}
    out = []
    t0 = time.perf_counter()
    for k, ((run, frame), pose) in enumerate(zip(rows, poses)):
        run = int(run)
        if run not in renderers:
            renderers[run] = PhysicsRender(run_paths[run], profile=profile)
        wrench = wrenches[k] if wrenches is not None else renderers[run].wrench[int(frame)]
        img = renderers[run].render(pose, wrench)
        if img.shape[:2] != (size, size):  # as the dataset resizes a frame (a non-square one too)
            img = cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)
        out.append(img)
    return out, (time.perf_counter() - t0) / max(1, len(out))
