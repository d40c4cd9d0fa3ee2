"""Do the stages move the contact the way the camera and the gauge say? (``rig check-axes``)

With the indenter pressed a little into the gel, each of x and y is moved by ±``step_mm`` and
θ by ±``twist_deg``, every move inside one motion session (rig/motion.py). Measured:

- **the camera**: where the contact is in the image, pressed at the start point and pressed
  again at each offset (lifted, moved in the air, pressed: a pure translation, no drag);
- **the gauge**: the change of Fx, Fy while the contact is dragged from each offset back to the
  start point, and of Mz between the two twists.

The image is the reference: by the run files' convention (docs/dataset.md, "Pose
convention") stage +x must move the contact right in the frame, +y up (rows run down), and θ
turn it counter-clockwise as the camera sees it. The gauge is expected to read, while
pressed, Fx and Fy along the motion that shears the gel and Mz along the twist (as the
simulated rig does). rig/axis_verdict.py turns the measurements into a verdict and a fix.

The images are read by a ``ContactImages`` (default rig/contact_image.py's, for any tactile gel):
``centre(reference, frame)`` is the contact's centre (column, row) in pixels, None when no
contact is visible; ``shift(reference, a, b)`` how far (columns, rows) the contact in ``b`` lies
from the one in ``a``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from rig.errors import DeviceTimeout, RigError


class ContactImages(Protocol):
    def centre(self, reference: np.ndarray, frame: np.ndarray) -> tuple[float, float] | None: ...

    def shift(self, reference: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[float, float]: ...


AVERAGED = 5  # gauge samples averaged for each reading
FRAME_WAIT_S = 5.0  # rig-clock seconds to wait for a frame taken after a move settled


@dataclass(frozen=True)
class CheckSettings:
    step_mm: float = 1.0  # each of x and y moves by ± this
    twist_deg: float = 5.0  # θ turns by ± this while pressed
    depth_mm: float | None = None  # press depth below the gel surface; None: a third of the gel
    clearance_mm: float = 0.5  # above the gel surface between presses

    def check(self) -> None:
        for name, value in (("step", self.step_mm), ("twist", self.twist_deg), ("clearance", self.clearance_mm)):
            if not (math.isfinite(value) and value > 0):
                raise RigError(f"check-axes: {name} must be finite and > 0, got {value!r}")
        if self.depth_mm is not None and not (math.isfinite(self.depth_mm) and self.depth_mm > 0):
            raise RigError(f"check-axes: depth must be finite and > 0, got {self.depth_mm!r}")


@dataclass
class Observation:
    """What the check measured (pixels: column right, row down, as the image stores them)."""

    frame_px: tuple[int, int]  # width, height
    start: dict[str, float]  # axis positions the check started from (x, y, θ)
    depth_mm: float
    step_mm: float
    twist_deg: float
    centre_px: tuple[float, float] = (math.nan, math.nan)  # the contact pressed at the start point
    offset_px: dict[tuple[str, int], tuple[float, float]] = field(default_factory=dict)  # (axis, ±1) -> shift
    shear_N: dict[tuple[str, int], tuple[float, float]] = field(default_factory=dict)  # (axis, ±1) -> ΔFx, ΔFy
    shear_noise_N: float = 0.0  # the spread of Fx, Fy at rest while pressed (1σ)
    press_fz_N: float = 0.0  # Fz pressed minus Fz clear of the gel
    twist_mz_Nmm: dict[int, float] = field(default_factory=dict)  # ±1 -> Mz turned by ±twist
    mz_noise_Nmm: float = 0.0


def check_depth(config, settings: CheckSettings) -> float:
    """The press depth (mm) ``settings`` asks of a rig with ``config``, refused before anything moves
    when the config states no gel or the press is deeper than the depth guard allows."""
    settings.check()
    safety = config.safety
    if safety is None or safety.gel_thickness_mm is None:
        raise RigError(
            "check-axes needs [safety] gel_thickness_mm in the rig config: the press depth and the depth guard "
            "come from it; nothing moved"
        )
    thickness = safety.gel_thickness_mm
    depth = settings.depth_mm if settings.depth_mm is not None else thickness / 3
    allowed = safety.max_depth_fraction * thickness
    if depth > allowed:
        raise RigError(
            f"check-axes: a press {depth:g} mm deep is deeper than the depth guard allows ({allowed:.2f} mm, "
            f"{safety.max_depth_fraction:.0%} of the {thickness:g} mm gel); nothing moved"
        )
    return depth


def check_axes(
    rig,
    images: ContactImages | None = None,
    settings: CheckSettings = CheckSettings(),
    *,
    on_start: Callable[[str], None] | None = None,
    on_note: Callable[[str], None] | None = None,
) -> Observation:
    """Press, move and twist as the module docstring says; returns the measurements. Needs x, y
    and z (θ optional), the camera, the gauge, and a remembered gel surface (rig find-contact)."""
    check_depth(rig.config, settings)
    if images is None:
        from rig.contact_image import GelContactImages

        images = GelContactImages()
    for name in ("x", "y", "z"):
        if name not in rig.axes:
            raise RigError(f"check-axes needs the x, y and z axes open; {name} is not")
    if rig.camera is None:
        raise RigError("check-axes needs the camera ([camera] in the rig config)")
    guard = rig.depth_guard()
    if guard is None:
        raise RigError("check-axes needs the gel surface: run rig find-contact first")
    depth = settings.depth_mm if settings.depth_mm is not None else guard.thickness_mm / 3
    if guard.surface_z - depth < guard.floor_z:
        raise RigError(f"check-axes: a press {depth:g} mm deep is below the depth guard's floor; {guard.describe()}")
    z_clear, z_press = guard.surface_z + settings.clearance_mm, guard.surface_z - depth
    start = {name: rig.axes[name].position() for name in ("x", "y", "theta") if name in rig.axes}
    step, twist = settings.step_mm, settings.twist_deg
    with rig.motion("axis check", on_start=on_start, on_note=on_note) as m:
        m.move({"z": max(rig.axes["z"].position(), z_clear)})
        reference = _frame(rig)
        clear = _wrench(rig)
        m.move({"z": z_press})
        pressed = _wrench(rig)
        height, width = reference.shape[:2]
        seen = Observation((width, height), start, depth, step, twist)
        seen.press_fz_N = float(pressed[0][2] - clear[0][2])
        seen.shear_noise_N = float(max(pressed[1][0], pressed[1][1]))
        centre = _frame(rig)
        seen.centre_px = _located(images, reference, centre, "pressed at the start point", depth)
        if "theta" in rig.axes:
            seen.mz_noise_Nmm = float(pressed[1][5])
            for sign in (1, -1):
                m.move({"theta": start["theta"] + sign * twist})
                seen.twist_mz_Nmm[sign] = float(_wrench(rig)[0][5])
            m.move({"theta": start["theta"]})
        m.move({"z": z_clear})
        for axis in ("x", "y"):
            for sign in (1, -1):
                m.move({axis: start[axis] + sign * step})  # in the air
                m.move({"z": z_press})
                where = f"pressed at {axis} {'+' if sign > 0 else '-'}{step:g} mm"
                frame = _frame(rig)
                _located(images, reference, frame, where, depth)
                dx, dy = images.shift(reference, centre, frame)
                seen.offset_px[(axis, sign)] = (float(dx), float(dy))
                before = _wrench(rig)[0]
                m.move({axis: start[axis]})  # dragged back in contact: the gel shears by -sign * step
                after = _wrench(rig)[0]
                seen.shear_N[(axis, sign)] = (float(after[0] - before[0]), float(after[1] - before[1]))
                m.move({"z": z_clear})
    return seen


def _located(images: ContactImages, reference: np.ndarray, frame: np.ndarray, where: str, depth: float):
    found = images.centre(reference, frame)
    if found is None:
        raise RigError(
            f"check-axes: no contact visible in the camera image {where}, {depth:g} mm into the gel: is the "
            "indenter over the gel pad, the camera looking at the gel and the light on? (rig camera snapshot)"
        )
    return (float(found[0]), float(found[1]))


def _frame(rig) -> np.ndarray:
    """A frame exposed after now: a triggered camera's next one; a free-running camera's second to
    arrive after now (its newest may be older, and the first after a move may have been exposed
    while the stage still settled: its time is its arrival)."""
    t = rig.clock.now()
    deadline = t + FRAME_WAIT_S
    needed = 1 if getattr(rig.camera, "triggered", False) else 2
    while True:
        rig.camera.trigger()
        frame = rig.camera.read(timeout_s=FRAME_WAIT_S)
        if frame.t_s >= t:
            needed -= 1
            if needed == 0:
                return frame.image
        if rig.clock.now() > deadline:
            raise DeviceTimeout(rig.camera.name, "read frame", None, "no frame exposed after the move settled")


def _wrench(rig) -> tuple[np.ndarray, np.ndarray]:
    """The mean of AVERAGED fresh gauge samples, and their spread (1σ per component)."""
    samples = np.array([rig.gauge.read_fresh().as_array() for _ in range(AVERAGED)])
    return samples.mean(axis=0), samples.std(axis=0)
