"""Grid convergence of flat punches, and whether force grows with depth, on the contact solver.

    .venv/bin/python bench/punch_convergence_bench.py [--sizes 32,64,128,256,512] [--tol 1e-8]

Flat punches (a circle of radius 1 mm, a square of side 2 mm) pressed 0.01 mm into a half-space
(E = 1 MPa, ν = 0.5) on grids of n² cells over 2.4 mm × 2.4 mm, solved to ``--tol``. The
circle has Boussinesq's closed form F = 2aE*d. Per grid the force error, the face's area as the
grid draws it against the true area (the cells whose centre lies on the face), and the force
scaled by √(true area / drawn area): a rigid punch's stiffness goes as √area (exact for the
circle, within 1 % for a square), so what is left after that scaling is the edge singularity's
share (the pressure ∝ 1/√(distance to the edge), which cells of uniform pressure cannot follow).
The drawn area goes up and down with the grid (a staircase outline), the scaled force converges
steadily (first order in the cell size): the square's reference is therefore the scaled force
Richardson-extrapolated from the two finest grids.

Then the library's flat objects centred on the simulated rig's 14 mm pad: the area each grid
draws against the true area, and the force error that predicts (√(drawn / true) − 1, plus the
edge share measured above at that cell size over the object's half-width).

Last, a 10 mm sphere on the 3 mm gel at 128 cells over 14 mm, force against depth by 1 µm steps
from 0.01 to 1.6 mm: each depth solved cold (``TactileContact``) at the simulated rig's tolerance,
1e-3 and 1e-6, and in sequence, warm-started from the depth before, as the simulated rig solves
(``rig_contact`` at its tolerance): the largest relative decrease of Fz between neighbouring
depths, and how many steps decrease.
"""

from __future__ import annotations

import argparse
import math
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from common.machine import describe
from objects.indenters import INDENTERS, sphere
from objects.pose import Pose
from sensor_sim.contact import SensorGeometry, TactileContact
from sensor_sim.elastomer import Elastomer
from sensor_sim.kernels import Kernels
from sensor_sim.normal_contact import solve_normal
from sensor_sim.world_contact import RIG_CELLS, RIG_TOL, rig_contact

GEL = Elastomer(E_MPa=1.0, nu=0.5, thickness_mm=math.inf)
DEPTH_MM, EXTENT_MM = 0.01, 2.4


def punch(kind: str, n: int, tol: float) -> tuple[float, float]:
    """(force N, area drawn mm²) of the punch on an n × n grid."""
    dx = EXTENT_MM / n
    x = (np.arange(n) - (n - 1) / 2) * dx
    X, Y = np.meshgrid(x, x)
    face = np.hypot(X, Y) <= 1.0 if kind == "circle" else (np.abs(X) <= 1.0) & (np.abs(Y) <= 1.0)
    h = np.where(face, 0.0, 50.0)
    s = solve_normal(Kernels(n, n, dx, GEL), h, DEPTH_MM, tol=tol, max_iter=5000)
    return s.force_N, float(face.sum()) * dx * dx


def convergence(sizes: list[int], tol: float) -> None:
    print("| punch | grid | cell mm | force error % | face area drawn / true | force × √(true / drawn) error % |")
    print("|---|---|---|---|---|---|")
    for kind, area in (("circle", math.pi), ("square", 4.0)):
        results = [(n, *punch(kind, n, tol)) for n in sizes]
        if kind == "circle":
            exact = 2 * 1.0 * GEL.E_star_MPa * DEPTH_MM
            note = "Boussinesq 2aE*d"
        else:  # Richardson, first order, of the area-scaled force from the two finest grids (by cell size)
            (n1, f1, a1), (n2, f2, a2) = results[-2], results[-1]
            s1, s2 = f1 * math.sqrt(area / a1), f2 * math.sqrt(area / a2)
            h1, h2 = EXTENT_MM / n1, EXTENT_MM / n2
            exact = s2 + (s2 - s1) * h2 / (h1 - h2)
            circle = 2 * GEL.E_star_MPa * DEPTH_MM * math.sqrt(area / math.pi)  # Boussinesq for the same area
            note = (
                f"area-scaled force Richardson-extrapolated from {n1}² and {n2}²: {exact:.6f} N = "
                f"{exact / circle:.4f} × the equal-area circle"
            )
        for n, force, drawn in results:
            scaled = force * math.sqrt(area / drawn)
            print(
                f"| {kind} | {n}² | {EXTENT_MM / n:.4f} | {100 * (force - exact) / exact:+.2f} | {drawn / area:.4f} | "
                f"{100 * (scaled - exact) / exact:+.2f} |"
            )
        print(f"|  | reference: {note} | | | | |")


EDGE_SHARE = 0.12  # the circle's area-scaled error is about −0.12 × cell / radius (table above)


def drawn_area(indenter, n: int) -> float:
    """mm² of the face an n × n grid over the 14 mm pad draws (the cells whose centre is on it)."""
    dx = 14.0 / n
    x = (np.arange(n) - (n - 1) / 2) * dx
    X, Y = np.meshgrid(x, x)
    return float((indenter.separation(X, Y) < 1.0).sum()) * dx * dx


def gel_force(indenter, n: int) -> float:
    """Fz (N) of the face centred on the default 3 mm gel, pressed 0.5 mm, n cells over 14 mm, tol 1e-6."""
    solver = TactileContact(indenter, Elastomer(), SensorGeometry(cells=n), tol=1e-6)
    return float(solver.solve(Pose(0.0, 0.0, -0.5, 0.0)).wrench[2])


def library_flats(cell_counts: list[int], finest: int = 512) -> None:
    """The library's flat faces centred on the 14 mm pad: drawn area, the force error that predicts on a
    half-space, and the force on the 3 mm gel pressed 0.5 mm against the ``finest`` grid's."""
    print(
        f"\n| object | cells over 14 mm | cell mm | face area drawn / true | predicted force error % (half-space) "
        f"| Fz on the 3 mm gel at 0.5 mm, N | against {finest} cells % |"
    )
    print("|---|---|---|---|---|---|---|")
    for name in ("circle4mm", "circle8mm", "square", "ring", "heart"):
        indenter = INDENTERS[name]()
        true = drawn_area(indenter, 4096)  # 3.4 µm cells: the true area to 1e-3
        reference = gel_force(indenter, finest)
        for n in cell_counts:
            dx = 14.0 / n
            ratio = drawn_area(indenter, n) / true
            predicted = 100 * (math.sqrt(ratio) * (1 - EDGE_SHARE * dx / (indenter.smallest_feature_mm / 2)) - 1)
            fz = gel_force(indenter, n)
            rig = " (the rig's)" if n == RIG_CELLS else ""
            print(
                f"| {name} | {n}{rig} | {dx:.4f} | {ratio:.4f} | {predicted:+.2f} | {fz:.3f} | "
                f"{100 * (fz - reference) / reference:+.2f} |",
                flush=True,
            )


def _dips(forces: np.ndarray) -> tuple[int, int, float]:
    steps = np.diff(forces)
    dips = steps < 0
    worst = float(np.max(-steps[dips] / forces[1:][dips])) if dips.any() else 0.0
    return len(steps), int(dips.sum()), worst


def monotonic(tols: list[float]) -> None:
    print("\n| sphere10mm, 128 cells over 14 mm, 3 mm gel | tol | steps | decreasing steps | largest relative dip |")
    print("|---|---|---|---|---|")
    depths = np.arange(0.01, 1.6, 0.001)
    for tol in tols:
        solver = TactileContact(sphere(10.0), Elastomer(), SensorGeometry(cells=128), tol=tol)
        forces = np.array([solver.solve(Pose(0.0, 0.0, -d, 0.0)).wrench[2] for d in depths])
        steps, dips, worst = _dips(forces)
        print(f"| each depth solved cold | {tol:g} | {steps} | {dips} | {worst:.1e} |", flush=True)
    rig = rig_contact(sphere(10.0), Elastomer(), SensorGeometry(cells=128))
    forces = np.array([rig.solve(Pose(0.0, 0.0, -d, 0.0)).wrench[2] for d in depths])
    steps, dips, worst = _dips(forces)
    print(f"| in sequence, warm-started (the rig's path) | {RIG_TOL:g} | {steps} | {dips} | {worst:.1e} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="32,64,128,256,512")
    ap.add_argument("--tol", type=float, default=1e-8)
    ap.add_argument("--skip-depth", action="store_true", help="no force-depth sweep")
    ap.add_argument("--skip-punch", action="store_true", help="not the half-space punches")
    args = ap.parse_args()
    print(f"machine: {describe()}\n")
    if not args.skip_punch:
        convergence([int(v) for v in args.sizes.split(",")], args.tol)
    library_flats([64, RIG_CELLS, 128, 256])
    if not args.skip_depth:
        monotonic([RIG_TOL, 1e-3, 1e-6])


if __name__ == "__main__":
    main()
