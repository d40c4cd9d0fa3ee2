"""One contact solve for an indenter pose: the wrench, and on request the fields.

Computes only what is asked: the normal problem is solved on the box where the
indenter can touch (contact needs h < d); the tangential problem only when there
is shear or twist; the full-sensor displacement fields (for optics and markers)
only when ``fields`` names them.

Past the gel thickness the indenter meets the rigid window (``backing.py``): the gel
is solved with the face clipped at the window and the window adds a steep contact
load, so force and image stay consistent and continuous in depth.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from objects.indenters import Indenter
from objects.pose import Pose
from sensor_sim.backing import NO_BACKING, BackingLoad, backing_load, gel_separation
from sensor_sim.elastomer import Elastomer, PhysicsInputError
from sensor_sim.kernels import kernels_for
from sensor_sim.normal_contact import NormalSolution, solve_normal
from sensor_sim.tangential_contact import TangentialSolution, solve_tangential

CELLS_PER_FEATURE = 2  # the fewest mechanics cells across an indenter's smallest feature


class UnresolvedFeature(PhysicsInputError):
    """An indenter whose smallest feature is under CELLS_PER_FEATURE mechanics cells: refused,
    since the grid would not see it (a contact force of zero that is not one)."""


def cells_to_resolve(indenter: Indenter, longer_side_mm: float) -> int:
    """The fewest cells across ``longer_side_mm`` that put CELLS_PER_FEATURE across the feature."""
    return math.ceil(CELLS_PER_FEATURE * longer_side_mm / indenter.smallest_feature_mm - 1e-9)


@dataclass(frozen=True)
class SensorGeometry:
    """The gel pad seen by the camera, and where the gauge measures moments."""

    width_mm: float = 14.0  # the GelSight Mini's shorter side, square as the paper's images
    height_mm: float = 14.0
    cells: int = 128  # mechanics grid cells across the longer side
    gauge_lever_mm: float = 25.0  # gauge origin above the gel surface, on the indenter axis

    @property
    def dx_mm(self) -> float:
        return max(self.width_mm, self.height_mm) / self.cells

    @property
    def shape(self) -> tuple[int, int]:
        return round(self.height_mm / self.dx_mm), round(self.width_mm / self.dx_mm)


@dataclass
class ContactResult:
    wrench: np.ndarray  # (6,) load on the gel: N and N·mm about the gauge origin
    normal: NormalSolution | None  # on the crop
    tangential: TangentialSolution | None
    crop: tuple[slice, slice] | None
    fields: dict[str, np.ndarray] = field(default_factory=dict)  # full sensor grid, mm
    solve_ms: float = 0.0
    backing: BackingLoad = NO_BACKING  # the window's share once the indenter reaches it
    # pressed in with its axis on the pad, yet no cell centre under the face: the contact is
    # narrower than a cell (the first micrometres of a press), its force below the grid's reach
    sub_cell: bool = False

    @property
    def in_contact(self) -> bool:
        return self.normal is not None and self.normal.force_N > 0

    @property
    def on_backing(self) -> bool:
        """The indenter is past the gel thickness: the gel is fully squeezed under it."""
        return self.backing.force_N > 0

    @property
    def converged(self) -> bool:
        """Every solve behind this result reached its tolerance."""
        return all(s.converged for s in (self.normal, self.tangential) if s is not None)

    @property
    def normal_iterations(self) -> int:
        return self.normal.iterations if self.normal is not None else 0

    @property
    def normal_residual(self) -> float:
        """Relative change of the pressure in the normal solve's last iteration."""
        return self.normal.residual if self.normal is not None else 0.0

    @property
    def tangential_iterations(self) -> int:
        return self.tangential.iterations if self.tangential is not None else 0

    @property
    def tangential_residual(self) -> float:
        """Relative change of the traction in the tangential solve's last iteration."""
        return self.tangential.residual if self.tangential is not None else 0.0


def _round_up(n: int, multiple: int = 8) -> int:
    return -(-n // multiple) * multiple


class TactileContact:
    def __init__(
        self,
        indenter: Indenter,
        gel: Elastomer | None = None,
        geometry: SensorGeometry | None = None,
        *,
        tol: float = 1e-3,
        tangential_tol: float = 1e-4,
    ):
        self.indenter = indenter
        self.gel = gel or Elastomer()
        self.geometry = geometry or SensorGeometry()
        self.tol = tol
        self.tangential_tol = tangential_tol
        ny, nx = self.geometry.shape
        dx = self.geometry.dx_mm
        feature = indenter.smallest_feature_mm
        if feature < CELLS_PER_FEATURE * dx:
            longer = max(self.geometry.width_mm, self.geometry.height_mm)
            raise UnresolvedFeature(
                f"{indenter.name}: its smallest feature ({feature:g} mm) spans fewer than {CELLS_PER_FEATURE} "
                f"mechanics cells of {dx:.3g} mm, so its contact would read as none: use at least "
                f"{cells_to_resolve(indenter, longer)} cells across the {longer:g} mm pad, or a larger object"
            )
        xs = (np.arange(nx) - (nx - 1) / 2) * dx
        ys = ((ny - 1) / 2 - np.arange(ny)) * dx  # row 0 is the top edge (+y), as in an image
        self.X, self.Y = np.meshgrid(xs, ys)

    def _crop(self, interference: np.ndarray) -> tuple[slice, slice]:
        rows = np.nonzero(interference.any(axis=1))[0]
        cols = np.nonzero(interference.any(axis=0))[0]
        ny, nx = interference.shape
        sl = []
        for idx, n in ((rows, ny), (cols, nx)):
            lo, hi = max(0, idx[0] - 2), min(n, idx[-1] + 3)
            size = min(n, _round_up(hi - lo))
            lo = max(0, min(lo, n - size))
            sl.append(slice(lo, lo + size))
        return sl[0], sl[1]

    def solve(
        self,
        pose: Pose,
        *,
        shift_mm: tuple[float, float] = (0.0, 0.0),
        twist_rad: float = 0.0,
        fields: frozenset[str] | set[str] = frozenset(),
        p0: np.ndarray | None = None,
        q0=None,
    ) -> ContactResult:
        """Solve at ``pose`` with the tangential motion since contact began.

        ``fields``: any of "uz" (surface sink), "uxy" (tangential displacement).
        ``p0``, ``q0``: warm starts, on the full sensor grid or on this solve's crop.
        A depth past the gel thickness presses the indenter on the window (see
        ``backing.py``): finite, continuous, reported in ``result.backing``.
        Raises PhysicsInputError for a non-finite pose.
        """
        t0 = time.perf_counter()
        for name, value in (("x", pose.x_mm), ("y", pose.y_mm), ("z", pose.z_mm), ("theta", pose.theta_deg)):
            if not math.isfinite(value):
                raise PhysicsInputError(f"pose {name} must be finite, got {value}")
        d = pose.depth_mm
        dx = self.geometry.dx_mm
        ny, nx = self.X.shape
        out = ContactResult(np.zeros(6), None, None, None)
        if d <= 0:
            zero = np.zeros((ny, nx))
            out.fields = {name: zero for name in fields if name == "uz"}
            if "uxy" in fields:
                out.fields["ux"] = out.fields["uy"] = zero
            return out
        h = self.indenter.separation_at(self.X, self.Y, pose.x_mm, pose.y_mm, pose.theta_deg)
        interference = h < d
        if not interference.any():
            half_w, half_h = self.geometry.width_mm / 2, self.geometry.height_mm / 2
            out.sub_cell = abs(pose.x_mm) <= half_w and abs(pose.y_mm) <= half_h
            out.solve_ms = (time.perf_counter() - t0) * 1e3
            return self.add_fields(out, fields)
        crop = self._crop(interference)
        hc = h[crop]
        Xc, Yc = self.X[crop], self.Y[crop]
        k = kernels_for(hc.shape[0], hc.shape[1], dx, self.gel)
        p_init = self._on_crop(p0, crop, hc.shape)
        overlap = d - self.gel.thickness_mm  # past the window plane where > 0
        normal = solve_normal(k, gel_separation(hc, d, self.gel.thickness_mm), d, tol=self.tol, p0=p_init)
        backing = backing_load(hc, Xc, Yc, overlap, dx * dx)
        tangential = None
        if (shift_mm != (0.0, 0.0) or twist_rad != 0.0) and normal.force_N > 0:
            qx_init = self._on_crop(q0[0], crop, hc.shape) if q0 is not None else None
            qy_init = self._on_crop(q0[1], crop, hc.shape) if q0 is not None else None
            q_init = (qx_init, qy_init) if qx_init is not None and qy_init is not None else None
            tangential = solve_tangential(
                k,
                normal.pressure_MPa,
                Xc,
                Yc,
                mu=self.gel.friction,
                shift_mm=shift_mm,
                twist_rad=twist_rad,
                center_mm=(pose.x_mm, pose.y_mm),
                tol=self.tangential_tol,
                q0=q_init,
            )
        cell = dx * dx
        p = normal.pressure_MPa
        fz = normal.force_N + backing.force_N
        mx = float(np.sum((Yc - pose.y_mm) * p)) * cell + (backing.y_mm - pose.y_mm) * backing.force_N
        my = -float(np.sum((Xc - pose.x_mm) * p)) * cell - (backing.x_mm - pose.x_mm) * backing.force_N
        fx = fy = mz = 0.0
        if tangential is not None:
            fx, fy, mz = tangential.fx_N, tangential.fy_N, tangential.mz_Nmm
        lever = self.geometry.gauge_lever_mm
        out.wrench = np.array([fx, fy, fz, mx + lever * fy, my - lever * fx, mz])
        out.normal, out.tangential, out.crop, out.backing = normal, tangential, crop, backing
        out = self.add_fields(out, fields)
        out.solve_ms = (time.perf_counter() - t0) * 1e3
        return out

    def _on_crop(self, guess: np.ndarray | None, crop: tuple[slice, slice], shape) -> np.ndarray | None:
        """A warm start on this solve's crop: a full-grid guess is cut to it (the contact moves
        across the grid, so an earlier crop's array would be shifted); a crop-sized one is used as is."""
        if guess is None:
            return None
        if guess.shape == self.X.shape:
            return guess[crop]
        return guess if guess.shape == shape else None

    def add_fields(self, out: ContactResult, fields) -> ContactResult:
        """Compute the displacement fields named in ``fields`` for a solve (also an earlier one)."""
        ny, nx = self.X.shape
        if not fields:
            return out
        full = kernels_for(ny, nx, self.geometry.dx_mm, self.gel)
        if "uz" in fields:
            p = np.zeros((ny, nx))
            if out.normal is not None:
                p[out.crop] = out.normal.pressure_MPa
            out.fields["uz"] = full.normal_displacement(p) if p.any() else p
        if "uxy" in fields:
            qx, qy = np.zeros((ny, nx)), np.zeros((ny, nx))
            if out.tangential is not None:
                qx[out.crop], qy[out.crop] = out.tangential.qx_MPa, out.tangential.qy_MPa
            if qx.any() or qy.any():
                out.fields["ux"], out.fields["uy"] = full.tangential_displacement(qx, qy)
            else:
                out.fields["ux"], out.fields["uy"] = qx, qy
        return out
