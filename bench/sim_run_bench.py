"""Frames/s of a simulated protocol run, this working tree against an older commit.

    .venv/bin/python bench/sim_run_bench.py [--old COMMIT] [--repeats 2] [--set motion.speed_mm_s=0.05]
        [--profile] [--errors]

Each run is `rig run-protocol PROTOCOL --sim` as the command line makes it
(cli/simulated.py's rig, the real drivers over ptys, acquisition into an HDF5 run file),
in a fresh process, with the old tree (``git archive COMMIT``) and this one taking turns,
so that both see the same machine load. Prints frames/s per run and the ratio of medians.

``--profile``: one more run of each under cProfile (every thread), its time split into
stages by the module each function belongs to (numpy and other library time goes to the
project function that called it): solve, render, ports, clock, writer, and the rest.

``--errors``: this tree's run, and the old tree's, against this tree's exact path (every
gauge sample solved at its own time instead of interpolated between solves, both contact
problems to a relative tolerance of 1e-5 instead of 1e-3), with gauge and camera noise off,
compared per frame: the wrench and the frame's pixels, max and RMS.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common.machine import describe

ROOT = Path(__file__).resolve().parents[1]
BASELINE = "aacd35882bedd37c992864a283c2c0a90c5d8214"  # main when issue 17's speed-up began
DEFAULT_SETTINGS = [
    "motion.depth_step_mm=0.8",
    "motion.shear_mm=1.0",
]  # levels 0.8 and 1.6 mm at the real 0.01 mm/s: 1,606 frames

# Profile stages: the first prefix of a function's file (relative to the tree) that matches.
STAGES = [
    ("solve", ("sensor_sim/contact", "sensor_sim/normal_contact", "sensor_sim/tangential_contact")),
    ("solve", ("sensor_sim/kernels", "sensor_sim/backing", "sensor_sim/world_contact", "objects/")),
    ("render", ("sensor_sim/optics", "sensor_sim/light", "rig/sim/camera_sim", "rig/drivers/camera")),
    ("ports", ("rig/sim/link", "rig/sim/modbus_rtu", "rig/sim/zaber_sim", "rig/sim/pr_drive_sim")),
    ("ports", ("rig/sim/ft300_sim", "rig/transport/", "rig/drivers/")),
    ("clock", ("rig/clock", "rig/sim/stream_clock", "rig/sim/world", "rig/sim/stage", "rig/sim/motion")),
    ("writer", ("acquisition/run_file", "acquisition/schema", "acquisition/lock")),
]
EXACT_TOL = 1e-5  # the exact path's solver tolerance (relative change of p and q per iteration)
BLOCKING = ("select", "acquire", "wait", "sleep", "poll")  # a thread waiting, not working


# -- the child: one run in one tree -------------------------------------------------------
def child(args) -> None:
    sys.path.insert(0, str(Path(args.root).resolve()))
    profilers = []
    if args.profile:
        import cProfile
        import threading

        original_run = threading.Thread.run

        def profiled_run(self):
            prof = cProfile.Profile(time.thread_time)  # CPU time: a thread waiting for the GIL is not working
            profilers.append(prof)
            prof.enable()
            try:
                original_run(self)
            finally:
                prof.disable()

        threading.Thread.run = profiled_run  # type: ignore[method-assign]
    import numpy as np

    import cli
    from acquisition.executor import Acquisition
    from cli.simulated import monitor_interval_s, simulated_rig_for
    from protocols.plan import Plan
    from protocols.spec import load_protocol

    assert Path(cli.__file__).resolve().is_relative_to(Path(args.root).resolve()), cli.__file__
    protocol = load_protocol(args.protocol, args.set or None)
    plan = Plan.of(protocol)
    out = Path(args.out)
    main_prof = None
    if args.profile:
        import cProfile

        main_prof = cProfile.Profile(time.thread_time)
        profilers.append(main_prof)
    t0, c0 = time.perf_counter(), time.process_time()
    with simulated_rig_for(protocol) as (rig, simulated, header):
        if args.no_noise:  # the error comparison: deterministic gauge and frames
            simulated.world.spec.gauge_noise = (0.0,) * 6
            rig.camera.source.renderer._noise = None
        if args.exact:  # the reference: every gauge sample solved, both problems to EXACT_TOL
            simulated.world.solve_every_sample = True
            simulated.world.contact.use_tolerance(EXACT_TOL)
        t_open = time.perf_counter() - t0
        acq = Acquisition(rig, plan, monitor_interval_s=monitor_interval_s(protocol))
        if main_prof is not None:
            main_prof.enable()
        t1 = time.perf_counter()
        result = acq.run(out, header=header)
        t_run = time.perf_counter() - t1
        if main_prof is not None:
            main_prof.disable()
        solves = getattr(simulated.world.contact, "solves", None)
    report = {
        "frames": result.frames,
        "status": result.status,
        "open_s": t_open,
        "run_s": t_run,
        "wall_s": time.perf_counter() - t0,
        "cpu_s": time.process_time() - c0,
        "solves": solves,
    }
    if args.profile:
        report["stages"] = stages(profilers, Path(args.root).resolve())
        if args.pstats:
            merged(profilers).dump_stats(args.pstats)
    if args.dump:
        import h5py

        from acquisition import schema as S

        with h5py.File(out, "r") as f:
            np.savez(args.dump, wrench=f[S.WRENCH][:], frames=f[S.FRAMES][:], t=f[S.T_FRAME][:])
    print("RESULT " + json.dumps(report))


def stages(profilers, root: Path) -> dict[str, float]:
    """Seconds per stage: each function's own time, library functions' time handed to
    the project functions that called them (split as their calls' own times were)."""
    stats = merged(profilers)
    if stats is None:
        return {}
    table = stats.stats
    root_s = str(root) + "/"
    return _stage_totals(table, root_s)


def merged(profilers):
    """Every thread's cProfile merged into one pstats.Stats (None: nothing ran)."""
    import pstats

    stats = None
    for prof in profilers:
        try:
            st = pstats.Stats(prof)
        except TypeError:  # a thread that ran nothing
            continue
        if stats is None:
            stats = st
        else:
            stats.add(st)
    return stats


def _stage_totals(table, root_s: str) -> dict[str, float]:
    def own_stage(func) -> str | None:
        filename, _, name = func
        if filename.startswith(root_s) and "/.venv/" not in filename and "site-packages" not in filename:
            rel = filename[len(root_s) :]
            for stage, prefixes in STAGES:
                if rel.startswith(prefixes):
                    return stage
            return "other"
        return None

    totals: dict[str, float] = {}

    def credit(func, seconds: float, depth: int = 0) -> None:
        stage = own_stage(func)
        if stage is None and func[0] == "~" and any(word in func[2] for word in BLOCKING):
            stage = "blocked"
        if stage is not None or depth > 12 or func not in table:
            stage = stage or "other"
            totals[stage] = totals.get(stage, 0.0) + seconds
            return
        callers = table[func][4]
        share = sum(c[2] for c in callers.values())  # own time per caller
        if not callers or share <= 0:
            totals["other"] = totals.get("other", 0.0) + seconds
            return
        for caller, c in callers.items():
            credit(caller, seconds * c[2] / share, depth + 1)

    for func, (_, _, tottime, _, _) in table.items():
        if tottime > 0:
            credit(func, tottime)
    return totals


# -- the parent ----------------------------------------------------------------------------
def run_child(root: Path, args, *, profile=False, no_noise=False, dump=None, exact=False) -> dict:
    with tempfile.TemporaryDirectory(prefix="simbench-") as tmp:
        cmd = [
            sys.executable,
            str(Path(__file__).resolve()),
            "--child",
            "--root",
            str(root),
            "--protocol",
            args.protocol,
            "--out",
            str(Path(tmp) / "run.h5"),
        ]
        for s in args.set:
            cmd += ["--set", s]
        if profile:
            cmd.append("--profile")
        if no_noise:
            cmd.append("--no-noise")
        if dump:
            cmd += ["--dump", str(dump)]
        if exact:
            cmd.append("--exact")
        done = subprocess.run(cmd, cwd=root, capture_output=True, text=True, timeout=7200)
        lines = [ln for ln in done.stdout.splitlines() if ln.startswith("RESULT ")]
        if done.returncode != 0 or not lines:
            raise SystemExit(f"run in {root} failed ({done.returncode}):\n{done.stdout[-2000:]}\n{done.stderr[-4000:]}")
        return json.loads(lines[-1][len("RESULT ") :])


def old_tree(commit: str, where: Path) -> Path:
    """The old commit's files (git archive: the repository's own state is untouched)."""
    tree = where / commit[:12]
    if not tree.exists():
        tree.mkdir(parents=True)
        archive = subprocess.run(["git", "archive", commit], cwd=ROOT, capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
    return tree


def error_table(fast: Path, exact: Path) -> list[tuple[str, float, float, str]]:
    import numpy as np

    a, b = np.load(fast), np.load(exact)
    rows = []
    dw = a["wrench"] - b["wrench"]
    names = ("Fx N", "Fy N", "Fz N", "Mx N·mm", "My N·mm", "Mz N·mm")
    for i, name in enumerate(names):
        span = float(np.abs(b["wrench"][:, i]).max())
        rows.append(
            (f"wrench {name}", float(np.abs(dw[:, i]).max()), float(np.sqrt(np.mean(dw[:, i] ** 2))), f"{span:.3g}")
        )
    dp = a["frames"].astype(np.int16) - b["frames"].astype(np.int16)
    rows.append(
        ("frame pixels (grey levels)", float(np.abs(dp).max()), float(np.sqrt(np.mean(dp.astype(float) ** 2))), "255")
    )
    rows.append(("t_frame s", float(np.abs(a["t"] - b["t"]).max()), 0.0, "—"))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--old", default=BASELINE, help="the commit to compare with (default: main before issue 17)")
    ap.add_argument("--old-tree", type=Path, help="use this checkout of the old commit instead of git archive")
    ap.add_argument("--protocol", default="sphere10mm")
    ap.add_argument("--set", action="append", default=None, help="KEY=VALUE for the protocol (both trees)")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--errors", action="store_true")
    ap.add_argument("--skip-timing", action="store_true")
    # child mode
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--root", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    ap.add_argument("--no-noise", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--dump", help=argparse.SUPPRESS)
    ap.add_argument("--exact", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--pstats", help=argparse.SUPPRESS)  # child: write the merged profile here
    args = ap.parse_args()
    if args.set is None:
        args.set = list(DEFAULT_SETTINGS)
    if args.child:
        child(args)
        return
    work = Path(tempfile.mkdtemp(prefix="simbench-trees-"))
    old = args.old_tree.resolve() if args.old_tree else old_tree(args.old, work)
    new = ROOT
    print(f"machine: {describe()}; load {os.getloadavg()[0]:.2f}")
    print(f"protocol: {args.protocol} {' '.join('--set ' + s for s in args.set)}; old {args.old[:12]} ({old})")
    sides = {"old": old, "new": new}
    if not args.skip_timing:
        runs: dict[str, list[dict]] = {"old": [], "new": []}
        for i in range(args.repeats):
            order = ("old", "new") if i % 2 == 0 else ("new", "old")
            for side in order:
                r = run_child(sides[side], args)
                runs[side].append(r)
                print(
                    f"  run {i + 1} {side}: {r['frames']} frames, run {r['run_s']:.1f} s "
                    f"({r['frames'] / r['run_s']:.1f} frames/s), whole process {r['wall_s']:.1f} s, "
                    f"cpu {r['cpu_s']:.1f} s, solves {r['solves']}, load {os.getloadavg()[0]:.1f}",
                    flush=True,
                )
        print()
        print("| tree | frames | run s (median) | frames/s (median) | cpu s / frame | contact solves |")
        print("|---|---|---|---|---|---|")
        med = {}
        for side in ("old", "new"):
            rs = runs[side]
            fps = statistics.median(r["frames"] / r["run_s"] for r in rs)
            med[side] = fps
            print(
                f"| {side} | {rs[0]['frames']} | {statistics.median(r['run_s'] for r in rs):.1f} | {fps:.1f} | "
                f"{1e3 * statistics.median(r['cpu_s'] / r['frames'] for r in rs):.2f} ms | {rs[0]['solves']} |"
            )
        print(f"\nspeed-up (median frames/s, new / old): {med['new'] / med['old']:.2f}x")
    if args.profile:
        print("\nprofile (cProfile, every thread; seconds of own time per frame, ms):")
        profs = {side: run_child(sides[side], args, profile=True) for side in ("old", "new")}
        names = ["solve", "render", "ports", "clock", "writer", "other", "blocked"]
        print("| tree | " + " | ".join(names) + " | total (not blocked) |")
        print("|---|" + "---|" * (len(names) + 1))
        for side, r in profs.items():
            st, n = r["stages"], r["frames"]
            busy = sum(v for k, v in st.items() if k != "blocked")
            print(
                f"| {side} | "
                + " | ".join(f"{1e3 * st.get(k, 0.0) / n:.2f}" for k in names)
                + f" | {1e3 * busy / n:.2f} |"
            )
    if args.errors:
        print("\napproximation error against this tree's exact path, noise off:")
        with tempfile.TemporaryDirectory(prefix="simbench-err-") as tmp:
            dumps = {name: Path(tmp) / f"{name}.npz" for name in ("exact", "new", "old")}
            timed = {
                "exact": run_child(new, args, no_noise=True, dump=dumps["exact"], exact=True),
                "new": run_child(new, args, no_noise=True, dump=dumps["new"]),
                "old": run_child(old, args, no_noise=True, dump=dumps["old"]),
            }
            for name, r in timed.items():
                print(f"  {name}: run {r['run_s']:.1f} s, {r['solves']} contact solves")
            print("| path | quantity | max abs error | RMS error | max abs value |")
            print("|---|---|---|---|---|")
            for side in ("new", "old"):
                for name, mx, rms, span in error_table(dumps[side], dumps["exact"]):
                    print(f"| {side} | {name} | {mx:.3g} | {rms:.3g} | {span} |")


if __name__ == "__main__":
    main()
