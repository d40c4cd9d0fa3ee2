"""`rig protocols list|show` and `rig run-protocol`: parse, then call the library."""

from __future__ import annotations

import os
from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from common.errors import ConfigError

console = Console()


def fmt_duration(s: float) -> str:
    h, rem = divmod(int(round(s)), 3600)
    m, sec = divmod(rem, 60)
    return f"{h}h{m:02d}m{sec:02d}s" if h else f"{m}m{sec:02d}s"


def list_protocols() -> None:
    from protocols.plan import Plan
    from protocols.spec import load_protocol, protocol_names

    table = Table(title="protocol library (protocols/library)")
    for col in ("name", "object", "sensor", "levels", "duration", "frames"):
        table.add_column(col)
    for name in protocol_names():
        p = load_protocol(name)
        plan = Plan.of(p)
        table.add_row(
            name, p.object, p.sensor, str(len(p.levels)), fmt_duration(plan.total_duration_s), str(plan.frame_count)
        )
    console.print(table)


def show_protocol(name: str, frame_px: int = 256, settings: list[str] | None = None) -> None:
    from acquisition.executor import disk_bytes
    from protocols.plan import Plan
    from protocols.spec import load_protocol

    p = load_protocol(name, settings)
    plan = Plan.of(p)
    table = Table(title=f"{p.name}: {p.description}")
    for col in ("#", "phase", "level", "to x, y, z mm / θ deg", "speed", "duration", "captured"):
        table.add_column(col)
    for s in plan.steps:
        speed = (
            f"{p.speed_mm_s:g} mm/s"
            if s.phase in ("press", "shear", "return")
            else (
                f"{p.twist_speed_deg_s:g} °/s" if s.phase in ("twist", "untwist") else f"{p.approach_speed_mm_s:g} mm/s"
            )
        )
        table.add_row(
            str(s.index),
            s.phase,
            str(s.level or "-"),
            f"{s.end[0]:+.2f}, {s.end[1]:+.2f}, {s.end[2]:+.2f} / {s.end[3]:+.1f}",
            speed,
            fmt_duration(s.duration_s),
            "yes" if s.captured else "no",
        )
    console.print(table)
    gb = disk_bytes(plan, (frame_px, frame_px, 3)) / 1e9
    console.print(f"file: {p.path}")
    console.print(
        f"duration: {fmt_duration(plan.total_duration_s)} ({plan.total_duration_s:.1f} s; "
        f"captured {plan.captured_duration_s:.1f} s)"
    )
    console.print(f"frames: {plan.frame_count} at {p.capture_hz:g} Hz")
    console.print(f"disk: about {gb:.2f} GB at {frame_px}x{frame_px} px (uncompressed frames)")


def check_new_run_path(out: Path) -> None:
    """``--out`` must name a new file in an existing, writable directory. Checked before any
    device opens, so a refused run never moves a stage and never touches an existing file;
    ConfigError names the path and says what was expected."""
    if os.path.lexists(out):  # lexists: a dangling link would be written through too
        raise ConfigError(
            str(out), "--out", f"exists; a run file is never overwritten: pass another --out, or --resume {out}"
        )
    directory = out.absolute().parent
    try:
        exists = directory.is_dir()
    except OSError as exc:  # a parent we may not search
        raise ConfigError(str(out), "--out", f"cannot look into {directory}: {exc.strerror}") from None
    if not exists:
        raise ConfigError(str(out), "--out", f"directory {directory} does not exist; create it first")
    # effective ids: the ones the file is created with (they differ under sudo -u / setuid)
    if not os.access(directory, os.W_OK | os.X_OK, effective_ids=os.access in os.supports_effective_ids):
        raise ConfigError(str(out), "--out", f"directory {directory} is not writable")


def run_protocol(
    name: str,
    *,
    out: Path | None,
    resume: Path | None,
    dry_run: bool,
    config: Path | None,
    sim: bool,
    origin: tuple[float, float, float, float],
    settings: list[str] | None = None,
    profile: Path | None = None,
) -> None:
    """``profile``: the simulated sensor's profile TOML (--sim only; default the shipped one)."""
    from acquisition.executor import disk_bytes, preflight
    from cli.session import check_profile_option, load_sim_profile
    from protocols.plan import AXES, Plan
    from protocols.spec import load_protocol

    check_profile_option(profile, sim)
    sensor_profile = load_sim_profile(profile) if sim else None  # a bad file is refused before anything opens
    protocol = load_protocol(name, settings)
    plan = Plan.of(protocol)
    origin_map = dict(zip(AXES, origin))
    if resume is not None and out is not None:
        raise ConfigError(str(out), "--out", f"give --out for a new run or --resume {resume}, not both")
    explicit_out = out is not None
    if resume is None and out is None:  # a new file every run: a second run never collides
        import datetime as dt

        out = Path("runs") / f"{protocol.name}-{dt.datetime.now().strftime('%Y%m%d-%H%M%S')}.h5"
        if not dry_run:
            try:
                out.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise ConfigError(str(out), "--out", f"cannot create {out.parent}: {exc.strerror}") from None
    if resume is None and (explicit_out or not dry_run):
        assert out is not None  # named above when neither --out nor --resume was given
        check_new_run_path(out)  # before any device opens: a refused --out moves nothing
    path = resume or out
    if dry_run:
        if sim:
            from rig.sim.rig_sim import SimulatedRig

            with SimulatedRig(profile=sensor_profile) as simulated:
                rig_config = simulated.config()
        else:
            from cli.session import resolve_config_path
            from rig.config import load_config

            rig_config = load_config(resolve_config_path(config))
        preflight(rig_config, plan, origin_map)
        console.print(
            f"dry run: {protocol.name} fits {rig_config.path}'s soft limits, axis speeds and depth guard "
            "(from --origin); nothing moved. The speed envelope is checked when the run starts: it needs "
            "the gauge's measured period (docs/safety.md)"
        )
        console.print(
            f"duration {fmt_duration(plan.total_duration_s)}, {plan.frame_count} frames, "
            f"about {disk_bytes(plan, (256, 256, 3)) / 1e9:.2f} GB at 256x256"
        )
        return
    from rig.interruption import SignalsAsExceptions

    # SIGINT, SIGTERM and SIGHUP become MotionInterrupted for the whole command: while the
    # stages move the run's motion session stops and lifts them and the file records which
    # signal; before or after, the rig still closes (a gauge left streaming breaks later commands).
    with SignalsAsExceptions():
        if sim:
            _run_sim(protocol, plan, path, resume is not None, origin_map, sensor_profile)
        else:
            _run_hw(protocol, plan, path, resume is not None, origin_map, config)


def _run_sim(protocol, plan, path, resume, origin, profile=None) -> None:
    from cli.simulated import monitor_interval_s, simulated_rig_for

    with simulated_rig_for(protocol, profile=profile) as (rig, simulated, header):
        _execute(
            rig,
            plan,
            path,
            resume,
            origin,
            header,
            monitor_interval_s=monitor_interval_s(protocol),
            solver_warnings=lambda: simulated.world.contact.solver_warnings,
        )


def _run_hw(protocol, plan, path, resume, origin, config) -> None:
    from cli.session import resolve_config_path
    from rig.config import load_config
    from rig.rig import Rig

    cfg_path = resolve_config_path(config)
    cfg = load_config(cfg_path)
    header = {
        "rig_config": Path(cfg_path).read_text(),
        "mm_per_px": cfg.camera.mm_per_px if cfg.camera and cfg.camera.mm_per_px is not None else float("nan"),
    }
    with Rig.open(cfg, camera=True) as rig:
        _execute(rig, plan, path, resume, origin, header, monitor_interval_s=None)


def _execute(rig, plan, path, resume, origin, header, monitor_interval_s, solver_warnings=None) -> None:
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from acquisition.executor import Acquisition
    from cli.console.run_progress import ProgressWriter

    sidecar = ProgressWriter(path, protocol=plan.protocol.name, frames=plan.frame_count, levels_mm=plan.protocol.levels)
    with (
        sidecar,
        Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TextColumn("{task.completed}/{task.total} frames"),
            TimeRemainingColumn(),
            TextColumn("{task.fields[wrench]}"),
            console=console,
            transient=False,
        ) as bar,
    ):
        task = bar.add_task(plan.protocol.name, total=plan.frame_count, wrench="")

        def on_progress(p):
            sidecar.update(p)  # RUN.h5.progress.json: what `rig console` shows while the run goes on
            bar.update(
                task,
                completed=p.frame,
                description=f"{plan.protocol.name} L{p.level} {p.phase:8s}",
                wrench=f"Fz {p.wrench[2]:6.2f} N  Fx {p.wrench[0]:+5.2f}  Fy {p.wrench[1]:+5.2f}  "
                f"Mz {p.wrench[5]:+6.2f} N·mm",
            )

        acq = Acquisition(
            rig,
            plan,
            origin=origin,
            monitor_interval_s=monitor_interval_s,
            progress=on_progress,
            solver_warnings=solver_warnings,
        )
        result = acq.run(path, resume=resume, header=header)
    colour = {"complete": "green", "interrupted": "yellow"}.get(result.status, "red")
    console.print(
        f"[{colour}]{result.status}[/]: {result.frames}/{plan.frame_count} frames in {path}"
        + (f" — {result.reason}" if result.reason else "")
    )
    if result.solver_warnings:
        console.print(
            f"[yellow]warning[/]: {result.solver_warnings} contact solves of the simulated sensor stopped "
            "short of their tolerance (recorded in the run file as run/sim_solver_warnings)"
        )
    if result.skews_s:
        console.print(
            f"wrench–frame skew: median {1e3 * sorted(result.skews_s)[len(result.skews_s) // 2]:.1f} ms, "
            f"max {1e3 * max(result.skews_s):.1f} ms (rig clock)"
        )
    if result.status != "complete":
        raise typer.Exit(3 if result.status == "interrupted" else 2)
