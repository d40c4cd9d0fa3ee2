"""Contact solver error against run time: Hertz (sphere) and the flat punch.

    .venv/bin/python bench/contact_bench.py [--plot docs/img/contact_error_vs_time.png] [--tols 1e-3,1e-10]

For each grid size and solver tolerance: relative error of force, contact radius
and peak pressure against the closed forms (half-space, paraboloid for Hertz), and
the median wall time of a cold solve (no warm start) on one core. The domain is 3
contact radii wide (2.4 for the punch); kernels are built once per grid, as in use.
The iterations column says "f64" where the solve stalled on float32's floor and went
on in double precision, and "not converged" where it stopped short of the tolerance.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from sensor_sim.elastomer import Elastomer
from sensor_sim.kernels import Kernels
from sensor_sim.normal_contact import solve_normal

GEL = Elastomer(E_MPa=1.0, nu=0.5, thickness_mm=math.inf)


def grid(n, extent):
    dx = extent / n
    x = (np.arange(n) - (n - 1) / 2) * dx
    return (*np.meshgrid(x, x), dx)


def timed_solve(k, h, d, tol, repeats):
    times, sol = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        sol = solve_normal(k, h, d, tol=tol)
        times.append((time.perf_counter() - t) * 1e3)
    return sol, statistics.median(times)


def _iterations(s) -> str:
    notes = (["f64"] if getattr(s, "float64", False) else []) + ([] if s.converged else ["not converged"])
    return f"{s.iterations} ({', '.join(notes)})" if notes else str(s.iterations)


def hertz_rows(sizes, tols, repeats):
    R, d = 5.0, 0.2
    a = math.sqrt(R * d)
    F = 4 / 3 * GEL.E_star_MPa * math.sqrt(R) * d**1.5
    p0 = 3 * F / (2 * math.pi * a * a)
    rows = []
    for n in sizes:
        X, Y, dx = grid(n, 3 * a)
        k = Kernels(n, n, dx, GEL)
        h = (X**2 + Y**2) / (2 * R)
        for tol in tols:
            s, ms = timed_solve(k, h, d, tol, repeats)
            a_num = math.sqrt(s.contact_area_mm2 / math.pi)
            rows.append(
                (
                    "Hertz",
                    n,
                    tol,
                    _iterations(s),
                    (s.force_N - F) / F,
                    (a_num - a) / a,
                    (s.pressure_MPa.max() - p0) / p0,
                    ms,
                )
            )
    return rows


def punch_rows(sizes, tols, repeats):
    a, d = 1.0, 0.05
    F = 2 * a * GEL.E_star_MPa * d
    rows = []
    for n in sizes:
        X, Y, dx = grid(n, 2.4 * a)
        k = Kernels(n, n, dx, GEL)
        h = np.where(np.hypot(X, Y) <= a, 0.0, 50.0)
        for tol in tols:
            s, ms = timed_solve(k, h, d, tol, repeats)
            a_num = math.sqrt(s.contact_area_mm2 / math.pi)
            rows.append(("flat punch", n, tol, _iterations(s), (s.force_N - F) / F, (a_num - a) / a, float("nan"), ms))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--plot", default=None, help="write the error-vs-time plot here (PNG)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--tols", default="1e-2,1e-3,1e-4,1e-6", help="comma-separated solver tolerances")
    args = ap.parse_args()
    sizes, tols = (32, 64, 128, 256), tuple(float(t) for t in args.tols.split(","))
    rows = hertz_rows(sizes, tols, args.repeats) + punch_rows(sizes, tols, args.repeats)
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores (one used), Python {platform.python_version()}, "
        f"numpy {np.__version__}\n"
    )
    print("| case | grid | tol | iterations | force err % | radius err % | peak p err % | ms / solve |")
    print("|---|---|---|---|---|---|---|---|")
    for case, n, tol, it, ef, ea, ep, ms in rows:
        peak = "—" if math.isnan(ep) else f"{100 * ep:+.2f}"
        print(f"| {case} | {n}² | {tol:g} | {it} | {100 * ef:+.3f} | {100 * ea:+.2f} | {peak} | {ms:.1f} |")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
        for ax, case in zip(axes, ("Hertz", "flat punch")):
            for n in sizes:
                pts = [(ms, abs(ef) * 100 + 1e-4) for c, nn, _, _, ef, _, _, ms in rows if c == case and nn == n]
                ax.loglog(*zip(*pts), "o-", label=f"{n}²")
            ax.axvline(20, color="grey", ls=":", lw=1)
            ax.axhline(1, color="grey", ls=":", lw=1)
            ax.set_title(f"{case}: |force error| vs time (tol 1e-2 → 1e-6)")
            ax.set_xlabel("wall time per solve, ms (one core)")
            ax.grid(True, which="both", alpha=0.3)
        axes[0].set_ylabel("force error, %")
        axes[0].legend(title="grid")
        fig.tight_layout()
        fig.savefig(args.plot, dpi=110)
        print(f"\nplot: {args.plot}")


if __name__ == "__main__":
    main()
