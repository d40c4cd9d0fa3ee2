"""Tangential contact with Coulomb friction: stick, partial slip, full slip, torsion.

Given the normal pressure p (fixed: the Goodman approximation, exact for ν = 0.5),
the indenter's rigid tangential displacement field δ(x, y) = (δx − θ(y − yc),
δy + θ(x − xc)) since contact began, find the traction q on the gel with |q| ≤ μp.
In stick the surface follows the indenter (u = δ); in slip |q| = μp along δ − u.
These are the optimality conditions of min ½⟨q, Cq⟩ − ⟨q, δ⟩ over |q_i| ≤ μp_i,
solved by accelerated projected gradient (FISTA; Beck & Teboulle 2009).

As in the normal solver, a solve that stops improving on float32's floor goes on in
float64, and one that stalls there too stops early with ``converged=False``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from sensor_sim.kernels import Kernels, c2r_2d, direct_transforms, irfft2_full, r2c_2d, rfft2_padded
from sensor_sim.stall import StallWatch

# Stalled: the residual has not halved in this many iterations. FISTA's slowest
# healthy case measured (a twist at 128²) halves it every ~130 iterations; on the
# float32 floor it never does again.
STALL_ITERATIONS = 250


@dataclass
class TangentialSolution:
    qx_MPa: np.ndarray
    qy_MPa: np.ndarray
    # the gel's tangential surface displacement (ux, uy), or how to compute it (one more
    # pair of transforms that the wrench does not need: done when first asked for)
    displacement: tuple[np.ndarray, np.ndarray] | Callable[[], tuple[np.ndarray, np.ndarray]] = field(repr=False)
    fx_N: float
    fy_N: float
    mz_Nmm: float  # about (xc, yc)
    stick_fraction: float  # share of the contact area that sticks
    iterations: int
    residual: float  # relative change of q in the last iteration
    converged: bool
    float64: bool = False  # switched to double precision after stalling on float32's floor

    @property
    def ux_mm(self) -> np.ndarray:
        return self._displacement()[0]

    @property
    def uy_mm(self) -> np.ndarray:
        return self._displacement()[1]

    def _displacement(self) -> tuple[np.ndarray, np.ndarray]:
        d = self.displacement  # read once: another thread may resolve it meanwhile
        if callable(d):
            d = d()
            self.displacement = d
        return d


def _sum(a: np.ndarray) -> float:
    return np.add.reduce(a, axis=None)


def _displacement(kernels: Kernels, precise: bool):
    """q -> u for stacked fields (2, ny, nx) = (x, y): ``kernels.tangential_displacement``
    with both fields in one forward and one inverse transform call (the same numbers:
    pocketfft transforms each slice alone); an iteration on a protocol's crop is mostly
    per-call overhead, so the padded input and the spectra live in buffers made once per
    solve (the same operations in the same order: bit for bit the plain calls, tested)."""
    kxx, kyy, kxy = kernels.tangential_hat64 if precise else kernels.tangential_hat
    dtype = np.float64 if precise else np.float32
    shape, ny, nx = kernels.shape, kernels.ny, kernels.nx
    if not direct_transforms():  # another scipy: the public calls

        def plain(q: np.ndarray) -> np.ndarray:
            f = rfft2_padded(q.astype(dtype, copy=False), shape)
            u_hat = np.stack((kxx * f[0] + kxy * f[1], kxy * f[0] + kyy * f[1]))
            return irfft2_full(u_hat, shape)[:, :ny, :nx].astype(np.float64)

        return plain

    padded = np.zeros((2, *shape), dtype)  # zero outside the crop, the crop rewritten each call
    u_hat = np.empty((2, *kxx.shape), np.result_type(kxx, np.complex64 if dtype == np.float32 else np.complex128))
    term = np.empty(kxx.shape, u_hat.dtype)

    def apply(q: np.ndarray) -> np.ndarray:
        padded[:, :ny, :nx] = q  # cast as astype(dtype) casts
        f = r2c_2d(padded)
        np.multiply(kxx, f[0], out=u_hat[0])
        np.multiply(kxy, f[1], out=term)
        np.add(u_hat[0], term, out=u_hat[0])
        np.multiply(kxy, f[0], out=u_hat[1])
        np.multiply(kyy, f[1], out=term)
        np.add(u_hat[1], term, out=u_hat[1])
        return c2r_2d(u_hat, shape)[:, :ny, :nx].astype(np.float64)

    return apply


def solve_tangential(
    kernels: Kernels,
    p_MPa: np.ndarray,
    X: np.ndarray,
    Y: np.ndarray,
    *,
    mu: float,
    shift_mm: tuple[float, float] = (0.0, 0.0),
    twist_rad: float = 0.0,
    center_mm: tuple[float, float] = (0.0, 0.0),
    tol: float = 1e-4,
    max_iter: int = 2000,
    q0: tuple[np.ndarray, np.ndarray] | None = None,
) -> TangentialSolution:
    """Traction for the imposed tangential motion; stops at ``tol`` (converged), on a
    stall in float64 or at ``max_iter`` (not converged).

    The iteration holds (x, y) pairs stacked, (2, ny, nx): one array operation does both
    components (on a protocol's crop an iteration is mostly per-call overhead)."""
    cell = kernels.dx * kernels.dy
    xc, yc = center_mm
    d = np.stack((shift_mm[0] - twist_rad * (Y - yc), shift_mm[1] + twist_rad * (X - xc)))
    bound = mu * p_MPa
    contact = p_MPa > 0
    if not contact.any() or mu == 0 or not np.any(d[:, contact]):
        zeros = np.zeros_like(p_MPa)
        return TangentialSolution(
            zeros,
            zeros.copy(),
            (zeros.copy(), zeros.copy()),
            0.0,
            0.0,
            0.0,
            1.0 if contact.any() else 0.0,
            0,
            0.0,
            True,
        )
    step = 1.0 / kernels.tangential_lipschitz
    # |q| ≤ bound: q·bound/max(|q|, bound), which is q inside the disc and 0 off the contact
    # (bound 0); the floor keeps 0/0 away where both are zero.
    floor = np.maximum(bound, 1e-300)
    mag, scale = np.empty_like(bound), np.empty_like(bound)

    def project(q: np.ndarray) -> np.ndarray:
        np.hypot(q[0], q[1], out=mag)
        np.maximum(mag, floor, out=scale)
        np.divide(bound, scale, out=scale)
        q *= scale
        return q

    if q0 is not None:
        q = project(np.stack(q0).astype(np.float64))
    else:
        q = project(np.where(contact, d, 0.0) * 1e30)  # full slip guess
    y, t = q, 1.0
    residual, it, converged, precise = np.inf, 0, False, False
    stall = StallWatch(STALL_ITERATIONS)
    displacement = _displacement(kernels, precise)
    for it in range(1, max_iter + 1):
        u = displacement(y)
        u -= d
        u *= step
        n = project(np.subtract(y, u, out=u))
        moved = n - q
        # Gradient-based adaptive restart (O'Donoghue & Candès 2015): drop the momentum
        # when it points uphill; turns FISTA's O(1/k²) into linear convergence here.
        # (np.add.reduce is np.sum without its argument handling: the same pairwise sums)
        if float(_sum((y - n) * moved)) > 0:
            t = 1.0
        t_new = (1 + np.sqrt(1 + 4 * t * t)) / 2
        w = (t - 1) / t_new
        change = float(_sum(np.abs(moved)))
        size = float(_sum(np.abs(n)))
        residual = change / size if size > 0 else 0.0
        moved *= w
        y = np.add(n, moved, out=moved)
        q, t = n, t_new
        if residual < tol:
            converged = True
            break
        if stall.stalled(residual, it):
            if precise:
                break  # stalled in float64 as well: tol is beyond reach
            precise = True
            stall.restart(residual, it)
            displacement = _displacement(kernels, precise)
            y, t = q, 1.0  # restart the momentum in double precision
    qx, qy = q[0], q[1]
    mag = np.hypot(qx, qy)
    sticking = contact & (mag < bound * (1 - 1e-3))
    fx = float(np.sum(qx)) * cell
    fy = float(np.sum(qy)) * cell
    mz = float(np.sum((X - xc) * qy - (Y - yc) * qx)) * cell
    final = precise
    return TangentialSolution(
        qx,
        qy,
        lambda: kernels.tangential_displacement(qx, qy, precise=final),
        fx,
        fy,
        mz,
        float(sticking.sum()) / float(contact.sum()),
        it,
        residual,
        converged,
        precise,
    )
