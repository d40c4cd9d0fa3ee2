"""The contact state at a pose that carries a measured tangential load.

A rig run's frame records the indenter's pose and the wrench the gauge measured, not the
friction history that led there. The normal problem depends on the pose alone (Goodman);
the tangential one depends on how far the indenter has moved since the contact last stuck
(``world_contact.ElastomerContact``'s anchor). This module finds that motion from the load
instead: the stick shift (sx, sy) and twist θ whose tangential solve carries the measured
Fx, Fy and Mz, so that the gel's tangential displacement (what moves the markers) can be
rendered from a pose and a wrench alone.

The response is linear while the contact sticks and softens as it slips, up to the Coulomb
bound μ·Fz. The start is the stick stiffness (three small probes), then Broyden's update
(Broyden 1965) as slip sets in. A tangential load beyond what friction can carry at this
pose (gauge noise, a real sensor's other friction) is scaled back to just inside the bound:
the state then is the onset of gross slip, which is where the load says the contact is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from objects.pose import Pose
from sensor_sim.contact import ContactResult, TactileContact
from sensor_sim.kernels import kernels_for
from sensor_sim.tangential_contact import TangentialSolution, solve_tangential

FORCE_TOL_N = 0.005  # half the FT300's wire resolution (0.01 N)
MOMENT_TOL_NMM = 0.05
SLIP_MARGIN = 0.98  # a load at the Coulomb bound is matched at this share of it
PROBE_MM = 1e-3  # stick-stiffness probes: small enough that almost all of the contact sticks


@dataclass
class LoadMatch:
    result: ContactResult  # the solve at the pose with the matched tangential state (and the fields asked for)
    shift_mm: tuple[float, float]
    twist_rad: float
    target: np.ndarray  # (Fx N, Fy N, Mz N·mm) matched, after scaling back to the friction bound
    error: np.ndarray  # matched minus target
    solves: int  # tangential solves spent
    scaled: bool  # the measured load was beyond the friction bound and was scaled back

    @property
    def matched(self) -> bool:
        return _within(self.error)


def contact_at_load(
    solver: TactileContact,
    pose: Pose,
    load,
    fields=frozenset(),
    *,
    max_solves: int = 12,
) -> LoadMatch:
    """The solve at ``pose`` whose tangential load is ``load`` (Fx N, Fy N, Mz N·mm), with ``fields``.

    Raises PhysicsInputError (from the solver) for a non-finite pose, ValueError for a
    non-finite load."""
    target = np.asarray(load, dtype=float).reshape(3)
    if not np.all(np.isfinite(target)):
        raise ValueError(f"tangential load must be finite (Fx N, Fy N, Mz N·mm), got {target.tolist()}")
    base = solver.solve(pose)
    zero = np.zeros(3)
    if not base.in_contact or base.normal is None or base.crop is None:
        return LoadMatch(solver.add_fields(base, fields), (0.0, 0.0), 0.0, zero, zero, 0, bool(np.any(target)))
    crop = base.crop
    p = base.normal.pressure_MPa
    Xc, Yc = solver.X[crop], solver.Y[crop]
    k = kernels_for(p.shape[0], p.shape[1], solver.geometry.dx_mm, solver.gel)
    mu = solver.gel.friction
    # Scale a load past the friction bound back inside it (force and moment together).
    scaled = False
    fz = base.normal.force_N
    reach = _reach(p, Xc - pose.x_mm, Yc - pose.y_mm, mu, solver.geometry.dx_mm**2)
    use = _usage(target, mu * fz, reach)
    if use > SLIP_MARGIN:
        target = target * (SLIP_MARGIN / use)
        scaled = True
    if _within(target):
        return LoadMatch(solver.add_fields(base, fields), (0.0, 0.0), 0.0, target, -target, 0, scaled)

    radius = max(math.sqrt(float(np.sum(p > 0))) * solver.geometry.dx_mm / 2, solver.geometry.dx_mm)
    solves = 0

    def load_at(s: np.ndarray, q0) -> tuple[np.ndarray, TangentialSolution]:
        nonlocal solves
        solves += 1
        t = solve_tangential(
            k,
            p,
            Xc,
            Yc,
            mu=mu,
            shift_mm=(float(s[0]), float(s[1])),
            twist_rad=float(s[2]),
            center_mm=(pose.x_mm, pose.y_mm),
            tol=solver.tangential_tol,
            q0=q0,
        )
        return np.array([t.fx_N, t.fy_N, t.mz_Nmm]), t

    # Stick stiffness: one small probe per degree of freedom (the twist as arc at the contact's radius).
    steps = np.array([PROBE_MM, PROBE_MM, PROBE_MM / radius])
    J = np.empty((3, 3))
    unit: list[tuple[np.ndarray, np.ndarray]] = []  # each probe's traction per unit motion
    zero_q = (np.zeros_like(p), np.zeros_like(p))
    for j in range(3):
        s = np.zeros(3)
        s[j] = steps[j]
        value, t = load_at(s, zero_q)
        J[:, j] = value / steps[j]
        unit.append((t.qx_MPa / steps[j], t.qy_MPa / steps[j]))
    s = _step(J, target)
    # While the contact sticks the traction is linear in the motion: the probes' combination is
    # the answer there, and a close start (the solver projects it onto the friction bound) past it.
    guess = (sum(s[j] * unit[j][0] for j in range(3)), sum(s[j] * unit[j][1] for j in range(3)))
    value, best = load_at(s, guess)
    best_err = target_error(value, target)
    best_s = s
    q0 = (best.qx_MPa, best.qy_MPa)
    while solves < max_solves and not _within(value - target):
        ds = _step(J, target - value)
        # Slip softens the response: a Newton step from the stick stiffness undershoots and
        # Broyden's update learns the softening; never more than double the motion at once.
        limit = np.maximum(np.abs(s), steps)
        ds = np.clip(ds, -limit, limit)
        new_value, t = load_at(s + ds, q0)
        dv = new_value - value
        denom = float(ds @ ds)
        if denom > 0:
            J = J + np.outer(dv - J @ ds, ds) / denom
        s, value, q0 = s + ds, new_value, (t.qx_MPa, t.qy_MPa)
        err = target_error(value, target)
        if err < best_err:
            best, best_err, best_s = t, err, s
    out = ContactResult(base.wrench.copy(), base.normal, best, crop, backing=base.backing)
    lever = solver.geometry.gauge_lever_mm
    out.wrench[0], out.wrench[1], out.wrench[5] = best.fx_N, best.fy_N, best.mz_Nmm
    out.wrench[3] += lever * best.fy_N
    out.wrench[4] -= lever * best.fx_N
    matched = np.array([best.fx_N, best.fy_N, best.mz_Nmm])
    return LoadMatch(
        solver.add_fields(out, fields),
        (float(best_s[0]), float(best_s[1])),
        float(best_s[2]),
        target,
        matched - target,
        solves,
        scaled,
    )


def target_error(value: np.ndarray, target: np.ndarray) -> float:
    """The mismatch in tolerance units (≤ 1 everywhere: matched)."""
    d = value - target
    return float(max(abs(d[0]) / FORCE_TOL_N, abs(d[1]) / FORCE_TOL_N, abs(d[2]) / MOMENT_TOL_NMM))


def _within(d: np.ndarray) -> bool:
    """Fx, Fy and Mz all within tolerance of zero."""
    return bool(abs(d[0]) <= FORCE_TOL_N and abs(d[1]) <= FORCE_TOL_N and abs(d[2]) <= MOMENT_TOL_NMM)


def _step(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(J, r)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(J, r, rcond=None)[0]


def _reach(p: np.ndarray, dx: np.ndarray, dy: np.ndarray, mu: float, cell: float) -> float:
    """The largest twisting moment friction can carry about the indenter's axis, N·mm."""
    return float(mu * np.sum(p * np.hypot(dx, dy))) * cell


def _usage(target: np.ndarray, force_bound_N: float, moment_bound_Nmm: float) -> float:
    """How much of the friction bound the load asks for (a simple interaction: the shares add
    in quadrature; exact at either end, conservative between)."""
    f = math.hypot(target[0], target[1]) / force_bound_N if force_bound_N > 0 else math.inf
    m = abs(target[2]) / moment_bound_Nmm if moment_bound_Nmm > 0 else math.inf
    return math.hypot(f, m) if math.isfinite(f) and math.isfinite(m) else math.inf


def depth_for_force(
    solver: TactileContact,
    x_mm: float,
    y_mm: float,
    theta_deg: float,
    fz_N: float,
    *,
    tol_N: float = FORCE_TOL_N,
    max_depth_mm: float | None = None,
) -> float:
    """The indentation depth (mm, ≥ 0) at which the object at (x, y, θ) presses with ``fz_N``:
    bisection on the normal solve, whose force grows with depth (past the gel's thickness the
    window takes over, steeply). ValueError for a force that is not finite and ≥ 0, or beyond
    what ``max_depth_mm`` (default: 1.5 × the gel's thickness, or 5 mm) reaches."""
    if not (math.isfinite(fz_N) and fz_N >= 0):
        raise ValueError(f"Fz must be a finite force ≥ 0 N pressing into the gel, got {fz_N}")
    if fz_N == 0:
        return 0.0
    thickness = solver.gel.thickness_mm
    top = max_depth_mm if max_depth_mm is not None else (1.5 * thickness if math.isfinite(thickness) else 5.0)

    def force(depth: float) -> float:
        return float(solver.solve(Pose(x_mm, y_mm, -depth, theta_deg)).wrench[2])

    if force(top) < fz_N:
        raise ValueError(f"Fz {fz_N:g} N is beyond what {top:g} mm of indentation gives here ({force(top):.3g} N)")
    lo, hi = 0.0, top
    for _ in range(60):
        mid = (lo + hi) / 2
        f = force(mid)
        if abs(f - fz_N) <= tol_N:
            return mid
        lo, hi = (mid, hi) if f < fz_N else (lo, mid)
        if hi - lo < 1e-6:
            break
    return (lo + hi) / 2
