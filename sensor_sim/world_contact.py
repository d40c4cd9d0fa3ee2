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

import dataclasses
import logging
import math
import threading

import numpy as np

from objects.indenters import Indenter, get_indenter
from objects.pose import Pose
from sensor_sim.contact import ContactResult, SensorGeometry, TactileContact, cells_to_resolve
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
        # The last two solves in contact, for the next one's warm start: (motion vector, p, qx, qy)
        # on the full grid (the contact moves across it, so crops do not line up).
        self._history: list[tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]] = []
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
            self._history = []

    def use_tolerance(self, tol: float) -> None:
        """Solve both problems to ``tol`` from now on (the bench's exact path uses 1e-5)."""
        with self._lock:
            self.solver.tol = self.solver.tangential_tol = tol
            self._cache_key, self._cache = None, None

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
            motion = self._motion(pose)
            p0, q0 = self._warm_start(motion)
            result = self.solver.solve(pose, shift_mm=shift, twist_rad=twist, fields=fields, p0=p0, q0=q0)
            self.solves += 1
            if not result.converged:
                self._count_unconverged(pose, result)
            if result.tangential is not None and result.tangential.stick_fraction == 0.0:
                self._follow_slip(pose, result)
            self._remember(motion, result)
            self._cache_key, self._cache = self._key(pose), result
            return result

    def _motion(self, pose: Pose) -> np.ndarray:
        """The pose as one vector in mm (the twist as arc length at the indenter's radius)."""
        arc = math.radians(pose.theta_deg) * max(self.indenter.radius_mm, 1.0)
        return np.array([pose.x_mm, pose.y_mm, pose.z_mm, arc])

    def _warm_start(self, motion: np.ndarray):
        """Full-grid (p0, q0) for the solve at ``motion``: the last solve's pressure and
        traction, extrapolated linearly when the two solves before it moved the same way.

        Consecutive protocol frames are 10 µm apart along one straight path, so the contact
        state changes almost linearly: the extrapolated guess halves the tangential
        iterations of the plain warm start (bench/sim_run_bench.py). A guess only starts
        the iterations; the solvers still stop at their tolerance.
        """
        if not self._history:
            return None, None
        m1, p1, qx1, qy1 = self._history[-1]
        q1 = (qx1, qy1) if qx1 is not None and qy1 is not None else None
        if len(self._history) < 2:
            return p1, q1
        m2, p2, qx2, qy2 = self._history[-2]
        a, b = m1 - m2, motion - m1
        na, nb = float(a @ a), float(b @ b)
        if na <= 0 or nb <= 0:
            return p1, q1
        along = float(a @ b)
        if along < 0.9 * math.sqrt(na * nb) or along > 2.0 * na:
            return p1, q1  # a turn, a reversal or a jump: no trend to follow
        r = along / na
        p = np.maximum(p1 + r * (p1 - p2), 0.0)
        if q1 is None or qx2 is None or qy2 is None:
            return p, q1
        return p, (qx1 + r * (qx1 - qx2), qy1 + r * (qy1 - qy2))

    def _remember(self, motion: np.ndarray, result: ContactResult) -> None:
        if not result.in_contact or result.normal is None or result.crop is None:
            self._history = []
            return
        shape = self.solver.X.shape
        p = np.zeros(shape)
        p[result.crop] = result.normal.pressure_MPa
        qx = qy = None
        if result.tangential is not None:
            qx, qy = np.zeros(shape), np.zeros(shape)
            qx[result.crop], qy[result.crop] = result.tangential.qx_MPa, result.tangential.qy_MPa
        self._history = [*self._history[-1:], (motion, p, qx, qy)]

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


RIG_TOL = 3e-3  # the simulated rig's solver tolerance (relative change of p and q per iteration)
RIG_CELLS = 96  # the simulated rig's mechanics cells across the default 14 mm pad
RIG_CELL_MM = 14.0 / RIG_CELLS  # the largest cell the simulated rig uses on any pad (0.146 mm)
MAX_RIG_CELLS = 1024  # a finer grid than this to resolve an object is refused (UnresolvedFeature)


def rig_cells(width_mm: float, height_mm: float) -> int:
    """Cells across the longer side of a ``width_mm`` × ``height_mm`` pad: RIG_CELLS on the
    default 14 mm pad, and cells of at most RIG_CELL_MM on a larger one."""
    return max(RIG_CELLS, math.ceil(max(width_mm, height_mm) / RIG_CELL_MM - 1e-9))


def rig_contact(
    indenter: Indenter | str, gel: Elastomer | None = None, geometry: SensorGeometry | None = None
) -> ElastomerContact:
    """The simulated rig's gel (a sensor profile's gel and pad, or the defaults): by default
    96 cells over the 14 mm pad (0.146 mm), well under 1 % force error for these contacts
    (docs/simulator.md) at half the cost of 128. An object whose smallest feature is under
    two cells gets a finer grid (refined, up to MAX_RIG_CELLS; beyond, UnresolvedFeature).

    Both problems stop at a relative change of ``RIG_TOL`` per iteration: warm-started from
    the frame before (10 µm away), the wrench stays within 0.01 N and 0.2 N·mm of solves
    to 1e-5, under one count of the FT300's wire format, at two thirds of the solver's
    time at 1e-3 (docs/benchmarks.md, "Simulated run")."""
    indenter = get_indenter(indenter) if isinstance(indenter, str) else indenter
    geometry = geometry or SensorGeometry(cells=RIG_CELLS)
    needed = cells_to_resolve(indenter, max(geometry.width_mm, geometry.height_mm))
    if geometry.cells < needed <= MAX_RIG_CELLS:
        geometry = dataclasses.replace(geometry, cells=needed)
    return ElastomerContact(indenter, gel, geometry, tol=RIG_TOL, tangential_tol=RIG_TOL)
