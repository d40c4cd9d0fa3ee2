"""`rig protocols list|show` and `rig run-protocol`: parse, then call the library."""

from __future__ import annotations

import os
from pathlib import Path

import typer
from rich.table import Table

from cli.options import fixed
from cli.run_display import output_console
from common.errors import ConfigError, ToolError

console = output_console()


# What a run file's frames take on disk against raw (acquisition/schema.py, bench/storage_bench.py): the
# simulated rig writes Blosc, whose ratio depends on the sensor and the object, measured on whole
# `rig run-protocol NAME --sim` files at 0.1 mm/s (723 frames) and 0.5 mm/s (273): rgb 0.62-0.79 (smooth
# indenters 0.62-0.67, the texture boards 0.76-0.79), rgb_markers 0.75-0.86 (boards the most), white_markers
# 0.66-0.71; the default-speed sphere10mm run (5,783 frames) 0.63. A camera's frames are HTJ2K (0.24-0.28
# of raw on real GelSight frames).
SIM_RATIO = {"rgb": (0.60, 0.80), "rgb_markers": (0.73, 0.88), "white_markers": (0.64, 0.74)}
CAMERA_RATIO = (0.24, 0.28)
STREAM_BYTES_PER_S = 25 * 64  # the simulated gauge's stream: samples/s x (7 float64 + a digest)
FRAME_PX = 256


def disk_estimate(plan, simulated: bool, frame_px: int = FRAME_PX) -> tuple[int, int, str]:
    """(raw bytes, the larger compressed estimate, one line saying both) for a run of ``plan``."""
    from acquisition.executor import disk_bytes

    raw = disk_bytes(plan, (frame_px, frame_px, 3))
    sensor = getattr(getattr(plan, "protocol", None), "sensor", "rgb")
    low, high = SIM_RATIO.get(sensor, (0.60, 0.88)) if simulated else CAMERA_RATIO
    where = "the simulated rig's frames, Blosc" if simulated else "camera frames, HTJ2K"
    # beside the frames: the reference frame and the object image (stored whole), and on the simulated rig
    # its full-rate wrench stream with its digests (measured 15-25 samples/s, 64 bytes each)
    fixed = 2 * frame_px * frame_px * 3 + (int(STREAM_BYTES_PER_S * plan.total_duration_s) if simulated else 0)
    text = (
        f"about {_sizes(low * raw + fixed, high * raw + fixed)} on disk ({where}; {_sizes(raw)} of raw frames at "
        f"{frame_px}x{frame_px})"
    )
    return raw, int(high * raw + fixed), text


def _sizes(low: float, high: float | None = None) -> str:
    """'751–876 MB', '1.14 GB'."""
    unit, scale, digits = ("GB", 1e9, 2) if (high or low) >= 1e9 else ("MB", 1e6, 0)
    if unit == "MB" and (high or low) < 10e6:
        digits = 1  # "about 3.9–4.7 MB", not "4–5 MB" nor "4–4 MB"
    a = f"{low / scale:.{digits}f}"
    if high is None or f"{high / scale:.{digits}f}" == a:  # both ends the same when rounded: one number
        return f"{a} {unit}"
    return f"{a}–{high / scale:.{digits}f} {unit}"


def fmt_duration(s: float) -> str:
    h, rem = divmod(int(round(s)), 3600)
    m, sec = divmod(rem, 60)
    return f"{h}h{m:02d}m{sec:02d}s" if h else f"{m}m{sec:02d}s"


class UnknownProtocol(ToolError):
    """A protocol name that is neither in the library nor a .toml file."""


def known_protocol(name: str) -> str:
    """``name`` when it is a library protocol or a .toml path; else one line with the nearest
    library names ("did you mean …?") and the whole library."""
    import difflib

    from protocols.spec import protocol_names

    if Path(name).suffix == ".toml":  # a file: the library is not looked at (it may not be readable)
        return name
    names = protocol_names()
    if name in names:
        return name
    close = difflib.get_close_matches(name, names, n=2, cutoff=0.6)
    hint = f"did you mean {' or '.join(close)}? " if close else ""
    raise UnknownProtocol(
        f"no protocol named {name!r} in the library; {hint}(the library: {', '.join(names)}; or give the path "
        "of a .toml protocol file)"
    )


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


def show_protocol(name: str, frame_px: int = FRAME_PX, settings: list[str] | None = None) -> None:
    from protocols.plan import Plan
    from protocols.spec import load_protocol

    p = load_protocol(known_protocol(name), settings)
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
    console.print(f"file: {p.path}")
    console.print(
        f"duration: {fmt_duration(plan.total_duration_s)} ({plan.total_duration_s:.1f} s; "
        f"captured {plan.captured_duration_s:.1f} s)"
    )
    console.print(f"frames: {plan.frame_count} at {p.capture_hz:g} Hz")
    if p.max_force_N is not None and p.max_torque_Nmm is not None:
        force = ", ".join(f"|{c}| ≤ {v:g}" for c, v in zip(("Fx", "Fy", "Fz"), p.max_force_N))
        torque = ", ".join(f"|{c}| ≤ {v:g}" for c, v in zip(("Mx", "My", "Mz"), p.max_torque_Nmm))
        console.print(
            f"limits: {force} N; {torque} N·mm (the protocol's [limits]; your rig config's [safety] must allow "
            "them: docs/protocols.md)",
            highlight=False,
            markup=False,
        )
    console.print(f"disk: {disk_estimate(plan, simulated=False, frame_px=frame_px)[2]}")
    console.print(f"      with --sim: {disk_estimate(plan, simulated=True, frame_px=frame_px)[2]}")


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
    origin: tuple[float, float, float, float] | None,
    settings: list[str] | None = None,
    profile: Path | None = None,
) -> None:
    """``profile``: the simulated sensor's profile TOML (--sim only; default the shipped one);
    ``origin`` None: the one remembered for the rig (rig find-contact --set-origin), else 0,0,0,0."""
    from cli.session import check_profile_option, load_sim_profile
    from protocols.plan import AXES, Plan
    from protocols.spec import load_protocol

    check_profile_option(profile, sim)
    sensor_profile = load_sim_profile(profile) if sim else None  # a bad file is refused before anything opens
    protocol = load_protocol(known_protocol(name), settings)
    plan = Plan.of(protocol)
    origin, said = resolve_origin(origin, config, sim)
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
    # printed once the rig (or the dry run's check) is past every refusal: an error stays one line
    origin_line = f"origin: x,y,z,theta = {','.join(fixed(v, 4, sign=False) for v in origin)} ({said})"
    if dry_run:
        checked, config_path = _dry_run(protocol, plan, origin_map, sim, config, sensor_profile)
        console.print(origin_line, highlight=False)
        console.print(
            f"dry run: {protocol.name} fits {config_path}'s soft limits, axis speeds, depth guard and "
            f"{checked} (from the origin above); nothing moved"
        )
        console.print(
            f"duration {fmt_duration(plan.total_duration_s)}, {plan.frame_count} frames, {disk_estimate(plan, sim)[2]}"
        )
        return
    # SIGINT, SIGTERM and SIGHUP are held while the rig opens, then become MotionInterrupted for
    # the whole command (rig/signal_safety.py): while the stages move the run's motion session
    # stops and lifts them and the file records which signal; before or after, the axes still
    # stop, z lifts when pressed and the rig closes (a gauge left streaming breaks later commands).
    if sim:
        _run_sim(protocol, plan, path, resume is not None, origin_map, sensor_profile, origin_line)
    else:
        _run_hw(protocol, plan, path, resume is not None, origin_map, config, origin_line)


def _dry_run(protocol, plan, origin, sim: bool, config: Path | None, profile) -> tuple[str, str]:
    """Check the run as it would start, on the rig it names, moving nothing: (what of the speed
    envelope was checked, the config's path). The rig's devices are opened to measure the
    envelope as the run does (its gauge's period, its axes' round trips); a rig that cannot be
    opened (held by another process, say) is checked against its config alone, and said so.
    Raises ProtocolRefused as the run would."""
    from acquisition.executor import ProtocolRefused, check_against_rig, preflight

    if sim:
        from cli.simulated import monitor_interval_s, simulated_rig_for

        with simulated_rig_for(protocol, profile=profile) as (rig, _, _):
            poll_s = check_against_rig(rig, plan, origin, monitor_interval_s(protocol))
            return f"the simulated rig's speed envelope (checked every {poll_s * 1000:.0f} ms)", "the simulated rig"
    from cli.session import resolve_config_path
    from rig.config import load_config
    from rig.errors import RigError
    from rig.rig import Rig

    cfg = load_config(resolve_config_path(config))
    preflight(cfg, plan, origin)
    try:
        with Rig.open(cfg, camera=False) as rig:
            rig.state.mounted = protocol.object  # as the run would mount it, in memory: a dry run changes nothing
            poll_s = check_against_rig(rig, plan, origin)
    except ProtocolRefused:
        raise
    except RigError as exc:
        return f"not its speed envelope: the rig could not be opened to measure it ({exc})", str(cfg.path)
    return f"the speed envelope measured on the rig now (checked every {poll_s * 1000:.0f} ms)", str(cfg.path)


ZERO_ORIGIN = (0.0, 0.0, 0.0, 0.0)


def resolve_origin(origin, config: Path | None, sim: bool) -> tuple[tuple[float, float, float, float], str]:
    """The run's origin and where it came from: --origin, the rig's remembered one, or 0,0,0,0."""
    if origin is not None:
        return tuple(origin), "from --origin"
    if not sim:
        from cli.session import resolve_config_path
        from rig.config import load_config
        from rig.rig_state import RigState, age_text

        state = RigState.for_config(load_config(resolve_config_path(config)))
        if state.origin is not None:
            return state.origin.values, (
                f"remembered by rig find-contact --set-origin {age_text(state.origin.t_unix)}, in {state.path}"
            )
        return ZERO_ORIGIN, "the default: no --origin given and none remembered (rig find-contact --set-origin)"
    return ZERO_ORIGIN, "the simulated rig's contact point"


def _run_sim(protocol, plan, path, resume, origin, profile=None, origin_line: str = "") -> None:
    from cli.simulated import monitor_interval_s, simulated_rig_for
    from rig.signal_safety import opened_safely

    with opened_safely(lambda: simulated_rig_for(protocol, profile=profile), lambda opened: opened[0]) as opened:
        rig, simulated, header = opened
        _execute(
            rig,
            plan,
            path,
            resume,
            origin,
            header,
            monitor_interval_s=monitor_interval_s(protocol),
            solver_warnings=lambda: simulated.world.contact.solver_warnings,
            origin_line=origin_line,
        )


def _run_hw(protocol, plan, path, resume, origin, config, origin_line: str = "") -> None:
    from cli.session import resolve_config_path
    from rig.config import load_config
    from rig.rig import Rig

    cfg_path = resolve_config_path(config)
    cfg = load_config(cfg_path)
    header = {
        "rig_config": Path(cfg_path).read_text(),
        "mm_per_px": cfg.camera.mm_per_px if cfg.camera and cfg.camera.mm_per_px is not None else float("nan"),
    }
    if cfg.camera is not None and cfg.camera.sensor_profile is not None:
        # the profile the config names for its camera (`rig sim serve` names its simulated sensor's)
        header["sensor_profile"] = _profile_record(str(cfg_path), cfg.camera.sensor_profile)
    from rig.signal_safety import opened_safely

    with opened_safely(lambda: Rig.open(cfg, camera=True, indenter=protocol.object)) as rig:
        _execute(rig, plan, path, resume, origin, header, monitor_interval_s=None, origin_line=origin_line)


def _profile_record(config_path: str, profile_path: str) -> str:
    """The record of the sensor profile a config's [camera] names; ConfigError naming the key."""
    from sensor_sim.profile import ProfileError, load_profile

    try:
        return load_profile(profile_path).record()
    except ProfileError as exc:
        raise ConfigError(config_path, "camera.sensor_profile", str(exc)) from None


def _execute(
    rig, plan, path, resume, origin, header, monitor_interval_s, solver_warnings=None, origin_line: str = ""
) -> None:
    from acquisition.executor import Acquisition
    from cli.console.run_progress import ProgressWriter
    from cli.run_display import RunDisplay

    if origin_line:
        console.print(origin_line, highlight=False)

    sidecar = ProgressWriter(path, protocol=plan.protocol.name, frames=plan.frame_count, levels_mm=plan.protocol.levels)
    with sidecar, RunDisplay(console, plan.protocol.name, plan.frame_count) as show:

        def on_progress(p):
            sidecar.update(p)  # RUN.h5.progress.json: what `rig console` shows while the run goes on
            show(p)

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
