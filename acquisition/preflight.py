"""What a run checks before it moves: a protocol's plan against the rig config (soft limits,
speeds, the depth floor, the speed envelope) and its [limits] against the rig's [safety], the
check period a run's speeds need, and a plan's raw disk estimate. Moves nothing:
``rig run-protocol --dry-run`` and acquisition/executor.py both call ``check_against_rig``.
"""

from __future__ import annotations

import contextlib
import math

import numpy as np

from protocols.plan import AXES, Plan
from rig.envelope import DepthGuard
from rig.errors import SafetyError
from rig.safety import check_speed, check_target
from rig.types import WRENCH_COMPONENTS, WRENCH_UNITS


class ProtocolRefused(SafetyError):
    """The protocol would leave the rig's soft limits or exceed a speed; nothing moved."""


def protocol_limits(config, protocol) -> np.ndarray | None:
    """The force/torque limits a protocol runs under: its [limits] (|Fx|, |Fy|, |Fz| N, |Mx|, |My|,
    |Mz| N·mm), which must fit inside the rig config's [safety]; None when it declares none (the
    rig's own). Raises ProtocolRefused naming the component, both values and the way out."""
    if getattr(protocol, "max_force_N", None) is None:
        return None
    wanted = np.array([*protocol.max_force_N, *protocol.max_torque_Nmm], dtype=float)
    if config.safety is None:
        raise ProtocolRefused(f"{protocol.path} declares [limits], but {config.path} has no [safety] to check them")
    have = np.array([*config.safety.max_force_N, *config.safety.max_torque_Nmm], dtype=float)
    over = np.nonzero(wanted > have * (1 + 1e-9))[0]
    if over.size:
        i = int(over[0])
        name, unit = WRENCH_COMPONENTS[i], WRENCH_UNITS[i]
        key = "max_force_N" if i < 3 else "max_torque_Nmm"
        raise ProtocolRefused(
            f"{protocol.name} reaches |{name}| up to {wanted[i]:g} {unit} ({protocol.path} [limits]: what pressing "
            f'this object this deep loads the gel with; docs/protocols.md, "Texture boards"), more than '
            f"{config.path} [safety] {key} allows ({have[i]:g} {unit}), so the run would stop partway: raise it where "
            "your sensor and gauge take that load, or press shallower (--set motion.max_depth_mm=...) with [limits] "
            "to match; nothing moved"
        )
    return wanted


def preflight(config, plan: Plan, origin: dict[str, float], *, depth=None, envelope=None, poll_s=None) -> None:
    """Check every waypoint and speed of the plan against the rig config; moves nothing.

    ``depth`` (rig.envelope.DepthGuard): no step below its floor. ``envelope``
    (rig.envelope.Envelope, with the check period ``poll_s``): every captured step at a speed
    the guard can stop in time (a captured step is never slowed: its frames are planned at
    its speed). Raises ProtocolRefused naming the step, the axis, the value and the limit.
    """
    protocol_limits(config, plan.protocol)
    for step in plan.steps:
        for pose in (step.start, step.end):
            for axis, value in zip(AXES, pose):
                if axis not in config.axes:
                    if value != 0:
                        raise ProtocolRefused(
                            f"protocol step {step.index} ({step.phase}) moves axis {axis}, "
                            f"which {config.path} does not configure"
                        )
                    continue
                try:
                    check_target(config.axes[axis], origin[axis] + value)
                except SafetyError as exc:
                    raise ProtocolRefused(
                        f"protocol step {step.index} ({step.phase}, level {step.level}): {exc}"
                    ) from None
        for axis, speed in step.speeds.items():
            if axis in config.axes:
                try:
                    check_speed(config.axes[axis], speed)
                except SafetyError as exc:
                    raise ProtocolRefused(f"protocol step {step.index} ({step.phase}): {exc}") from None
    if depth is None and config.safety is not None and config.safety.gel_thickness_mm is not None:
        depth = DepthGuard(
            origin["z"], "the protocol's origin", config.safety.gel_thickness_mm, config.safety.max_depth_fraction
        )
    if depth is not None and "z" in config.axes:
        lowest = min(plan.steps, key=lambda step: step.end[2])
        z = origin["z"] + lowest.end[2]
        if z < depth.floor_z - 1e-6:
            raise ProtocolRefused(
                f"protocol step {lowest.index} ({lowest.phase}, level {lowest.level}) goes to z = {z:.3f} mm, "
                f"{depth.surface_z - z:.2f} mm below the gel surface: {depth.describe()}; lower "
                "motion.max_depth_mm, or raise [safety] max_depth_fraction if your gel allows it"
            )
    if envelope is not None:
        _preflight_speeds(plan, origin, depth, envelope, poll_s or config.safety.poll_s)


def _preflight_speeds(plan: Plan, origin: dict[str, float], depth, envelope, poll_s: float) -> None:
    """Every captured step inside the envelope: z pressing into the gel at the gel's cap,
    sideways and twisting steps below the surface at the pressed caps."""
    surface = depth.surface_z if depth is not None else None
    for step in plan.captured_steps:
        pressed = surface is None or origin["z"] + min(step.start[2], step.end[2]) < surface
        for axis, speed in step.speeds.items():
            if axis == "z":
                if step.end[2] >= step.start[2]:
                    continue  # lifting
                cap = envelope.cap("z", "gel", poll_s)
            elif not pressed:
                continue
            else:
                cap = envelope.cap(axis, "pressed", poll_s)
            if speed > cap.speed * (1 + 1e-9):
                raise ProtocolRefused(
                    f"protocol step {step.index} ({step.phase}, level {step.level}): {axis} at {speed:g} {cap.unit}/s "
                    f"is faster than the speed envelope's {cap.speed:.3g} {cap.unit}/s {cap.why()}"
                )


def fitted_interval(config, plan: Plan, origin: dict[str, float], envelope, depth, asked: float) -> float:
    """The check period: the one asked for, shortened where a captured step's speed needs more
    frequent checks to stay inside the speed envelope (never below the rig's poll_s; preflight
    refuses a step that even that cannot make safe)."""
    interval = asked
    surface = depth.surface_z if depth is not None else None
    for step in plan.captured_steps:
        pressed = surface is None or origin["z"] + min(step.start[2], step.end[2]) < surface
        for axis, speed in step.speeds.items():
            if axis not in config.axes or (axis == "z" and step.end[2] >= step.start[2]):
                continue
            if axis != "z" and not pressed:
                continue
            longest = envelope.longest_poll_s(axis, "gel" if axis == "z" else "pressed", speed)
            interval = min(interval, max(config.safety.poll_s, longest))
    # A whole fraction of the period asked for: the checks stay on the capture grid, and the
    # measured timing's jitter does not move them (a simulated run is the same run every time).
    return asked / math.ceil(asked / interval - 1e-9) if interval < asked else asked


def check_against_rig(rig, plan: Plan, origin: dict[str, float], asked_poll_s: float | None = None) -> float:
    """Everything the run checks before it moves, on an open rig (its measured speed envelope, its
    remembered surface or the origin, the protocol's [limits]); returns the check period the run
    would use. Raises ProtocolRefused. Moves nothing (``rig run-protocol --dry-run`` calls it)."""
    hint = (origin["z"], "the protocol's origin (--origin)")
    depth = rig.depth_guard(hint)
    limits = protocol_limits(rig.config, plan.protocol)
    with contextlib.ExitStack() as stack:
        if limits is not None:
            stack.enter_context(rig.narrowed_limits(limits))
        envelope = rig.envelope()
        poll_s = fitted_interval(rig.config, plan, origin, envelope, depth, asked_poll_s or rig.config.safety.poll_s)
        preflight(rig.config, plan, origin, depth=depth, envelope=envelope, poll_s=poll_s)
    return poll_s


def disk_bytes(plan: Plan, frame_shape: tuple[int, int, int]) -> int:
    per_frame = int(np.prod(frame_shape)) + 8 * (6 + 4 + 4 + 3) + 8 + 4 + 2
    return plan.frame_count * per_frame
