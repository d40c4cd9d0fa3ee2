"""The one physical world behind every simulated device of a rig.

Four stages (x, y, z, θ) carry the indenter; the contact model turns the pose into
the wrench the gauge simulators report, and (later) the surface the camera renders.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from objects.pose import Pose
from rig.clock import Clock
from rig.sim.contact import ContactModel
from rig.sim.stage import SimStage, StageSpec

AXES = ("x", "y", "z", "theta")


@dataclass(frozen=True)
class AxisGeometry:
    """Where the contact point is in stage coordinates, and which way is +."""

    origin: float  # stage position (from home) at the contact point
    sign: float = 1.0  # +1: stage + is world +; -1: stage + is world -


@dataclass
class WorldSpec:
    stages: dict[str, StageSpec] = field(
        default_factory=lambda: {
            # x, y: 25 mm stages homing at one end; contact point mid-travel.
            "x": StageSpec(travel=(0.0, 25.0), max_speed=5.0, accel=20.0),
            "y": StageSpec(travel=(0.0, 25.0), max_speed=5.0, accel=20.0),
            # z homes at the top and moves down; the gel surface is 20 mm below home.
            "z": StageSpec(travel=(0.0, 25.0), max_speed=5.0, accel=20.0),
            "theta": StageSpec(travel=(0.0, 360.0), max_speed=30.0, accel=120.0),
        }
    )
    geometry: dict[str, AxisGeometry] = field(
        default_factory=lambda: {
            "x": AxisGeometry(origin=12.5),
            "y": AxisGeometry(origin=12.5),
            "z": AxisGeometry(origin=20.0, sign=-1.0),
            "theta": AxisGeometry(origin=180.0),
        }
    )
    # Start above the contact point, 5 mm clear of the gel, already homed.
    start: dict[str, float] = field(default_factory=lambda: {"x": 12.5, "y": 12.5, "z": 15.0, "theta": 180.0})
    gauge_offset: tuple[float, ...] = (0.12, -0.08, 0.35, 4.0, -3.0, 1.5)  # unloaded bias, N / N·mm
    gauge_noise: tuple[float, ...] = (0.002, 0.002, 0.004, 0.05, 0.05, 0.05)  # 1σ per sample


class SimWorld:
    def __init__(self, clock: Clock, spec: WorldSpec | None = None, contact: ContactModel | None = None, seed: int = 0):
        self.clock = clock
        self.spec = spec or WorldSpec()
        if contact is None:
            from sensor_sim.world_contact import ElastomerContact

            contact = ElastomerContact("sphere10mm")
        self.contact = contact
        self._last_true: tuple[float, np.ndarray] | None = None
        self.stages = {name: SimStage(name, self.spec.stages[name], position=self.spec.start[name]) for name in AXES}
        self._rng = np.random.default_rng(seed)
        # True: every gauge sample is solved at its own time instead of interpolated between
        # one solve per tick (the reference path bench/sim_run_bench.py measures against).
        self.solve_every_sample = False

    def pose(self, t_s: float | None = None) -> Pose:
        t = self.clock.now() if t_s is None else t_s
        rel = {}
        for name in AXES:
            g = self.spec.geometry[name]
            rel[name] = g.sign * (self.stages[name].position(t) - g.origin)
        return Pose(rel["x"], rel["y"], rel["z"], rel["theta"])

    def true_wrench(self, t_s: float | None = None) -> np.ndarray:
        """The load on the gel, without gauge bias or noise."""
        return self.contact.wrench(self.pose(t_s))

    def gauge_wrench(self, t_s: float | None = None) -> np.ndarray:
        """What a gauge measures: load + unloaded bias + noise (tare removes the bias)."""
        return self.gauge_samples([self.clock.now() if t_s is None else t_s])[0]

    def gauge_samples(self, times: list[float]) -> np.ndarray:
        """(n, 6) gauge samples at ``times`` (ascending), with one physics solve at most.

        The load is solved at the last time and interpolated from the previous call's
        last sample for the earlier ones: a stream of thousands of samples a second
        costs one contact solve per simulator tick (on the discrete-event clock, one per
        advance, whose last sample is at the new time itself). Noise is drawn per sample.
        """
        if not times:
            return np.zeros((0, 6))
        if self.solve_every_sample:
            out = np.array([self.true_wrench(t) for t in times])
            self._last_true = (times[-1], out[-1])
            noise = self._rng.normal(0.0, 1.0, (len(times), 6)) * np.asarray(self.spec.gauge_noise)
            return out + np.asarray(self.spec.gauge_offset) + noise
        t_end = times[-1]
        end = self.true_wrench(t_end)
        start_t, start = self._last_true if self._last_true is not None else (t_end, end)
        self._last_true = (t_end, end)
        if t_end <= start_t:
            w = np.ones(len(times))
        else:
            w = np.clip((np.asarray(times, dtype=np.float64) - start_t) / (t_end - start_t), 0.0, 1.0)
        out = start + (end - start) * w[:, None]
        noise = self._rng.normal(0.0, 1.0, (len(times), 6)) * np.asarray(self.spec.gauge_noise)
        return out + np.asarray(self.spec.gauge_offset) + noise
