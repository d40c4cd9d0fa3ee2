"""A protocol expanded into steps, and the timeline they make.

Pure code: no hardware. A step is a straight move (all listed axes arrive together,
the path at the protocol's speed) or a twist; captures happen on a fixed grid of
protocol time, ``k / capture_hz``, over the captured steps. Poses are relative to
the contact point: x, y, z in mm (z < 0 pressed in), θ in degrees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from common.errors import ConfigError
from protocols.spec import Protocol

AXES = ("x", "y", "z", "theta")

# Caps on an expansion, so that no protocol (a 1e-300 mm depth step, a 1e-4 mm/s crawl at
# 100 Hz) can hang the planner or plan a run no disk holds.
MAX_LEVELS = 127  # a frame's level is stored as int8 in the run file (acquisition/schema.py)
MAX_STEPS = 10_000  # the paper's sequence is 9 steps per level: 127 levels need 1,145
MAX_FRAMES = 1_000_000  # ~200 GB of 256x256 RGB frames, 170x the paper's 5,783 per object


@dataclass(frozen=True)
class Step:
    index: int
    phase: str  # approach, press, shear, return, twist, untwist, retract
    level: int  # depth level, 1-based (0 before and after)
    start: tuple[float, float, float, float]
    end: tuple[float, float, float, float]
    speeds: dict[str, float]  # per axis, mm/s or deg/s
    duration_s: float
    captured: bool

    def pose_at(self, t_s: float) -> tuple[float, float, float, float]:
        f = 0.0 if self.duration_s == 0 else min(1.0, max(0.0, t_s / self.duration_s))
        x, y, z, theta = (a + (b - a) * f for a, b in zip(self.start, self.end))
        return x, y, z, theta


PHASES = ("approach", "press", "shear", "return", "twist", "untwist", "retract")


def _move(index, phase, level, start, end, speed, captured) -> Step:
    """A straight move at path speed ``speed`` (mm/s); θ-only moves at ``speed`` deg/s."""
    dxyz = [end[i] - start[i] for i in range(3)]
    dist = math.sqrt(sum(d * d for d in dxyz))
    dtheta = end[3] - start[3]
    if dist > 0:
        duration = dist / speed
    else:
        duration = abs(dtheta) / speed
    speeds = {}
    for axis, d in zip(AXES, [*dxyz, dtheta]):
        if d:
            speeds[axis] = abs(d) / duration
    return Step(index, phase, level, tuple(start), tuple(end), speeds, duration, captured)


def expand(p: Protocol) -> list[Step]:
    """The paper's sequence (docs/reference.md, "The acquisition protocol"), level by level.

    Raises ConfigError naming the protocol's file and key when the expansion would pass
    MAX_LEVELS or MAX_STEPS; it is counted before anything is built.
    """
    n_levels = round(p.max_depth_mm / p.depth_step_mm)
    if n_levels > MAX_LEVELS:
        raise ConfigError(
            p.path,
            "motion.depth_step_mm",
            f"max_depth_mm / depth_step_mm = {p.max_depth_mm} / {p.depth_step_mm} is {n_levels} levels; "
            f"the planner's cap is {MAX_LEVELS} (a level is stored as int8)",
        )
    per_level = 1 + (6 if p.shear_mm > 0 else 0) + (2 if p.twist_deg > 0 else 0)
    if 2 + n_levels * per_level > MAX_STEPS:
        raise ConfigError(
            p.path, "motion.depth_step_mm", f"{2 + n_levels * per_level} steps; the planner's cap is {MAX_STEPS}"
        )
    steps: list[Step] = []
    s, v = p.shear_mm, p.speed_mm_s
    pose = (0.0, 0.0, p.approach_mm, 0.0)

    def add(phase, level, end, speed, captured=True):
        nonlocal pose
        steps.append(_move(len(steps), phase, level, pose, end, speed, captured))
        pose = tuple(end)

    add("approach", 0, (0.0, 0.0, 0.0, 0.0), p.approach_speed_mm_s, captured=False)
    for level, depth in enumerate(p.levels, start=1):
        z = -depth
        add("press", level, (0.0, 0.0, z, 0.0), v)
        if s > 0:
            add("shear", level, (0.0, s, z, 0.0), v)
            add("shear", level, (s, s, z, 0.0), v)
            add("return", level, (0.0, 0.0, z, 0.0), v)
            add("shear", level, (0.0, -s, z, 0.0), v)
            add("shear", level, (-s, -s, z, 0.0), v)
            add("return", level, (0.0, 0.0, z, 0.0), v)
        if p.twist_deg > 0:
            add("twist", level, (0.0, 0.0, z, p.twist_deg), p.twist_speed_deg_s)
            add("untwist", level, (0.0, 0.0, z, 0.0), p.twist_speed_deg_s)
    add("retract", 0, (0.0, 0.0, p.approach_mm, 0.0), p.approach_speed_mm_s, captured=False)
    return steps


@dataclass(frozen=True)
class Plan:
    protocol: Protocol
    steps: list[Step]

    @classmethod
    def of(cls, protocol: Protocol) -> "Plan":
        """The plan of ``protocol``; ConfigError (file, key, the cap) when it passes MAX_LEVELS,
        MAX_STEPS or MAX_FRAMES."""
        plan = cls(protocol, expand(protocol))
        frames = plan.frame_count
        if frames > MAX_FRAMES:
            raise ConfigError(
                protocol.path,
                "capture.rate_hz",
                f"{frames} frames ({plan.captured_duration_s:.0f} s captured at "
                f"{protocol.capture_hz:g} Hz); "
                f"the planner's cap is {MAX_FRAMES}: raise motion.speed_mm_s or lower capture.rate_hz",
            )
        return plan

    @property
    def captured_steps(self) -> list[Step]:
        return [s for s in self.steps if s.captured]

    @property
    def captured_duration_s(self) -> float:
        return sum(s.duration_s for s in self.captured_steps)

    @property
    def total_duration_s(self) -> float:
        return sum(s.duration_s for s in self.steps)

    @property
    def frame_count(self) -> int:
        """Captures at t = k / rate for every k with t within the captured steps (both ends)."""
        return math.floor(self.captured_duration_s * self.protocol.capture_hz + 1e-9) + 1

    def capture_time(self, k: int) -> float:
        return k / self.protocol.capture_hz

    def locate(self, t_s: float) -> tuple[Step, float]:
        """The captured step running at protocol time ``t_s`` and the time into it."""
        elapsed = 0.0
        captured = self.captured_steps
        for step in captured:
            if t_s <= elapsed + step.duration_s + 1e-9:
                return step, t_s - elapsed
            elapsed += step.duration_s
        return captured[-1], captured[-1].duration_s

    def pose_at(self, t_s: float) -> tuple[float, float, float, float]:
        step, into = self.locate(t_s)
        return step.pose_at(into)

    def extremes(self) -> dict[str, tuple[float, float]]:
        """Lowest and highest value each axis reaches, relative to the contact point."""
        out = {}
        for i, axis in enumerate(AXES):
            values = [s.start[i] for s in self.steps] + [s.end[i] for s in self.steps]
            out[axis] = (min(values), max(values))
        return out
