"""The simulated gauge's physics hook.

``ContactModel.wrench(pose)`` returns the load the indenter applies to the gel,
[Fx, Fy, Fz] N and [Mx, My, Mz] N·mm in the sensor frame (Fz > 0 pressing in).
``SpringContact`` is a closed-form stand-in for the elastomer solver
(``sensor_sim.world_contact.ElastomerContact``) where a test needs speed, not an
image: Hertz-like normal force, a stick-slip tangential spring with Coulomb friction,
and a torsional spring with its slip limit.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from objects.pose import Pose


class ContactModel(Protocol):
    def wrench(self, pose: Pose) -> np.ndarray:
        """(6,) load on the gel: N and N·mm."""


@dataclass
class SpringContact:
    normal_N_per_mm15: float = 6.0  # Fz = k d^1.5, ~ a 10 mm sphere on a soft gel
    tangential_N_per_mm: float = 3.0
    torsion_Nmm_per_deg: float = 2.0
    friction: float = 0.6
    lever_mm: float = 2.0  # effective radius for the torsional slip limit

    def __post_init__(self):
        self._anchor: tuple[float, float, float] | None = None
        self._lock = threading.Lock()

    @property
    def solver_warnings(self) -> int:
        """Unconverged solves, as ``ElastomerContact`` counts them: none, this is closed form."""
        return 0

    def wrench(self, pose: Pose) -> np.ndarray:
        d = pose.depth_mm
        with self._lock:
            if d <= 0:
                self._anchor = None
                return np.zeros(6)
            fz = self.normal_N_per_mm15 * d**1.5
            if self._anchor is None:
                self._anchor = (pose.x_mm, pose.y_mm, pose.theta_deg)
            ax, ay, at = self._anchor
            fx = self.tangential_N_per_mm * (pose.x_mm - ax)
            fy = self.tangential_N_per_mm * (pose.y_mm - ay)
            ft = math.hypot(fx, fy)
            limit = self.friction * fz
            if ft > limit:  # gross slip: the anchor follows so the traction stays at μFz
                scale = limit / ft
                fx, fy = fx * scale, fy * scale
                ax = pose.x_mm - fx / self.tangential_N_per_mm
                ay = pose.y_mm - fy / self.tangential_N_per_mm
            mz = self.torsion_Nmm_per_deg * (pose.theta_deg - at)
            mz_limit = self.friction * fz * self.lever_mm
            if abs(mz) > mz_limit:
                mz = math.copysign(mz_limit, mz)
                at = pose.theta_deg - mz / self.torsion_Nmm_per_deg
            self._anchor = (ax, ay, at)
        # A tangential load applied at the gel surface, measured at a gauge a lever
        # above it, shows as a moment about the other tangential axis.
        mx = -fy * self.lever_mm
        my = fx * self.lever_mm
        return np.array([fx, fy, fz, mx, my, mz])
