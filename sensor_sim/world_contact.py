"""The elastomer as the simulated rig's physics: pose → wrench, with friction history.

Tangential load depends on the motion since contact began (the anchor). When the
contact slides fully, the anchor follows, so that reversing the motion unloads at
once (gross slip, as on a real gel). Results are cached on the pose quantised to
``quantum_mm`` / ``quantum_deg``: a slow protocol asks for the same pose many times.

Past the gel thickness the indenter presses on the window (``backing.py``): the
gauge sees a steep, finite, continuous rise and the camera the fully squeezed gel.
A solve that does not reach its tolerance is counted (``solver_warnings``) and
logged once per contact model, so that a run can record how many frames it affects.
"""

from __future__ import annotations

import logging
import math
import threading

import numpy as np

from objects.indenters import Indenter, get_indenter
from objects.pose import Pose
from sensor_sim.contact import ContactResult, SensorGeometry, TactileContact
from sensor_sim.elastomer import Elastomer

log = logging.getLogger(__name__)


class ElastomerContact:
    def __init__(
        self,
        indenter: Indenter | str = "sphere10mm",
        gel: Elastomer | None = None,
        geometry: SensorGeometry | None = None,
        *,
        quantum_mm: float = 0.5e-3,
        quantum_deg: float = 0.005,
        tol: float = 1e-3,
        tangential_tol: float = 1e-3,
    ):
        indenter = get_indenter(indenter) if isinstance(indenter, str) else indenter
        # A live gauge needs low latency more than the last 0.1 % (see docs/simulator.md).
        self.solver = TactileContact(indenter, gel, geometry, tol=tol, tangential_tol=tangential_tol)
        self.quantum_mm, self.quantum_deg = quantum_mm, quantum_deg
        self._anchor: tuple[float, float, float] | None = None
        self._cache_key: tuple | None = None
        self._cache: ContactResult | None = None
        self._lock = threading.Lock()
        self.solves = 0
        self._solver_warnings = 0
        if math.isfinite(self.solver.gel.thickness_mm):
            # ~0.5 s of Bessel quadrature, done before the first sample needs it.
            from sensor_sim.kernels import warm_tables

            threading.Thread(target=warm_tables, args=(self.solver.gel.nu,), daemon=True).start()

    @property
    def indenter(self) -> Indenter:
        return self.solver.indenter

    @property
    def solver_warnings(self) -> int:
        """Solves since construction that stopped short of their tolerance (never reset)."""
        return self._solver_warnings

    def reset(self) -> None:
        """Forget the friction history (the stick anchor) and the cached solve."""
        with self._lock:
            self._anchor, self._cache_key, self._cache = None, None, None

    def _key(self, pose: Pose) -> tuple:
        q, qd = self.quantum_mm, self.quantum_deg
        return (
            round(pose.x_mm / q),
            round(pose.y_mm / q),
            round(pose.z_mm / q),
            round(pose.theta_deg / qd),
            self._anchor,
        )

    def solve(self, pose: Pose, fields=frozenset()) -> ContactResult:
        """Full result at ``pose`` (with the fields asked for), advancing the friction history."""
        with self._lock:
            if pose.depth_mm <= 0:
                self._anchor = None
            elif self._anchor is None:
                self._anchor = (pose.x_mm, pose.y_mm, pose.theta_deg)
            key = self._key(pose)
            if key == self._cache_key and self._cache is not None:
                missing = self._missing(self._cache, fields)
                if missing:  # same contact, more asked of it: only the extra fields
                    self.solver.add_fields(self._cache, missing)
                return self._cache
            shift, twist = (0.0, 0.0), 0.0
            if self._anchor is not None:
                ax, ay, at = self._anchor
                shift, twist = (pose.x_mm - ax, pose.y_mm - ay), math.radians(pose.theta_deg - at)
            # the last solve, if it had a contact, warm-starts this one
            prev_n = self._cache.normal if self._cache is not None else None
            prev_t = self._cache.tangential if self._cache is not None and prev_n is not None else None
            result = self.solver.solve(
                pose,
                shift_mm=shift,
                twist_rad=twist,
                fields=fields,
                p0=prev_n.pressure_MPa if prev_n is not None else None,
                q0=(prev_t.qx_MPa, prev_t.qy_MPa) if prev_t is not None else None,
            )
            self.solves += 1
            if not result.converged:
                self._count_unconverged(pose, result)
            if result.tangential is not None and result.tangential.stick_fraction == 0.0:
                self._follow_slip(pose, result)
            self._cache_key, self._cache = self._key(pose), result
            return result

    def _count_unconverged(self, pose: Pose, result: ContactResult) -> None:
        self._solver_warnings += 1
        if self._solver_warnings == 1:  # once per model: a gauge solves hundreds of times a second
            log.warning(
                "contact solve did not converge at %s (normal: %d iterations, residual %.2g; tangential: "
                "%d iterations, residual %.2g; tolerances %g / %g); further ones are only counted in "
                "solver_warnings",
                pose,
                result.normal_iterations,
                result.normal_residual,
                result.tangential_iterations,
                result.tangential_residual,
                self.solver.tol,
                self.solver.tangential_tol,
            )

    @staticmethod
    def _missing(result: ContactResult, fields) -> set[str]:
        have = {"uz"} if "uz" in result.fields else set()
        if "ux" in result.fields:
            have.add("uxy")
        return set(fields) - have

    def _follow_slip(self, pose: Pose, result: ContactResult) -> None:
        """Full slip: move the anchor so the solved state is the onset of sliding."""
        t, n = result.tangential, result.normal
        assert t is not None and n is not None, "full slip is only known after a tangential solve"
        w = n.pressure_MPa
        total = float(w.sum())
        ux = float((t.ux_mm * w).sum()) / total
        uy = float((t.uy_mm * w).sum()) / total
        Xc, Yc = self.solver.X[result.crop] - pose.x_mm, self.solver.Y[result.crop] - pose.y_mm
        r2 = float((w * (Xc**2 + Yc**2)).sum())
        rot = float((w * (Xc * t.uy_mm - Yc * t.ux_mm)).sum()) / r2 if r2 > 0 else 0.0
        self._anchor = (pose.x_mm - ux, pose.y_mm - uy, pose.theta_deg - math.degrees(rot))

    def wrench(self, pose: Pose) -> np.ndarray:
        return self.solve(pose).wrench.copy()


def rig_contact(indenter: str) -> ElastomerContact:
    """The simulated rig's gel: 96 cells over the 14 mm pad (0.146 mm), well under 1 %
    force error for these contacts (docs/simulator.md) at half the cost of 128."""
    return ElastomerContact(indenter, geometry=SensorGeometry(cells=96))
