"""Normal contact of a rigid indenter on the gel: displacement-controlled
Polonsky–Keer conjugate gradient (Polonsky & Keer, Wear 231, 1999), FFT-accelerated.

Unknown: pressure p ≥ 0 per cell (MPa). Given the indenter's separation h ≥ 0 from
its lowest point (mm) and the approach d (mm), the gap g = u(p) + h − d must satisfy
g ≥ 0, p ≥ 0, p·g = 0. The contact set is solved for, not fixed; with the approach
imposed, PK's load-balancing mean correction is dropped.

Precision: the transforms run in float32, whose floor (a relative change of p of
~1e-7 on 32² to ~1e-6 on 256²) lies above a very tight ``tol``. A solve that stops
improving on that floor switches to float64 and goes on; one that stalls in float64
too stops early with ``converged=False`` instead of spending ``max_iter``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from sensor_sim.kernels import Kernels
from sensor_sim.stall import StallWatch

REFRESH = 8  # iterations between full recomputations of the displacement
# Stalled: the residual has not halved in this many iterations. Four refresh cycles:
# PK's residual is not monotone while the contact set settles, but on every bench
# case (32²..256², Hertz and punch) it halves within 2 cycles until the float32 floor.
STALL_ITERATIONS = 4 * REFRESH


@dataclass
class NormalSolution:
    pressure_MPa: np.ndarray  # (ny, nx)
    # (ny, nx) surface sink, positive into the gel: an array, or how to compute it (one
    # more transform that the wrench does not need: done when first asked for)
    displacement: np.ndarray | Callable[[], np.ndarray] = field(repr=False)
    force_N: float
    contact_area_mm2: float
    iterations: int
    residual: float  # relative change of p in the last iteration
    converged: bool
    float64: bool = False  # switched to double precision after stalling on float32's floor

    @property
    def contact(self) -> np.ndarray:
        return self.pressure_MPa > 0

    @property
    def displacement_mm(self) -> np.ndarray:
        d = self.displacement  # read once: another thread may resolve it meanwhile
        if callable(d):
            d = d()
            self.displacement = d
        return d


def solve_normal(
    kernels: Kernels,
    h_mm: np.ndarray,
    depth_mm: float,
    *,
    tol: float = 1e-4,
    max_iter: int = 500,
    p0: np.ndarray | None = None,
) -> NormalSolution:
    """Solve the contact of separation ``h_mm`` pressed ``depth_mm`` into the gel.

    Stops at ``tol`` (converged), on a stall in float64 or at ``max_iter`` (not converged).
    """
    cell = kernels.dx * kernels.dy
    target = depth_mm - h_mm  # interference where positive
    if depth_mm <= 0 or not np.any(target > 0):
        zero = np.zeros_like(h_mm)
        return NormalSolution(zero, zero.copy(), 0.0, 0.0, 0, 0.0, True)
    conv: Callable[[np.ndarray], np.ndarray] = kernels.normal_displacement  # float32 until a stall
    if p0 is None or not np.any(p0 > 0):
        # Scale the interference into a pressure that best matches it on the overlap.
        p = np.maximum(target, 0.0)
        u1 = conv(p)
        m = p > 0
        p *= float(np.sum(target[m] * u1[m]) / np.sum(u1[m] ** 2))
    else:
        p = np.where(p0 > 0, p0, 0.0)
    t = np.zeros_like(p)
    delta, G_old = 0.0, 1.0
    residual, it, converged, precise = np.inf, 0, False, False
    stall = StallWatch(STALL_ITERATIONS)
    u = conv(p)
    for it in range(1, max_iter + 1):
        g = u - target
        S = p > 0
        G = float(np.sum(g[S] ** 2))
        t = np.where(S, g + (delta * G / G_old) * t, 0.0)
        G_old = G if G > 0 else 1.0
        r = conv(t)
        denom = float(np.sum(r[S] * t[S]))
        if denom <= 0:
            converged = True
            break
        tau = float(np.sum(g[S] * t[S])) / denom
        p_step = p - tau * t  # t is zero off the contact set
        p_new = np.maximum(p_step, 0.0)
        overlap = (p_new == 0) & (g < 0)
        if overlap.any():
            delta = 0.0
            p_new = np.where(overlap, -tau * g, p_new)
        else:
            delta = 1.0
        # u is linear in p: u(p_step) = u - tau·r exactly; only the (sparse, and soon
        # empty) projection/overlap corrections need a transform of their own. A full
        # refresh every REFRESH iterations keeps single-precision drift away.
        correction = p_new - p_step
        if it % REFRESH == 0:
            u = conv(p_new)
        elif np.any(correction):
            u = u - tau * r + conv(correction)
        else:
            u = u - tau * r
        total = float(np.sum(p_new))
        residual = float(np.sum(np.abs(p_new - p))) / total if total > 0 else 0.0
        p = p_new
        if residual < tol:
            converged = True
            break
        if stall.stalled(residual, it):
            if precise:
                break  # stalled in float64 as well: tol is beyond reach
            # Restart CG in double precision from the current pressure.
            precise, conv = True, lambda f: kernels.normal_displacement(f, precise=True)
            stall.restart(residual, it)
            u, t, delta, G_old = conv(p), np.zeros_like(p), 0.0, 1.0
    final = conv
    return NormalSolution(
        p,
        lambda: final(p),
        float(np.sum(p)) * cell,
        float(np.count_nonzero(p)) * cell,
        it,
        residual,
        converged,
        precise,
    )
