"""``rig``: status, jog, home, zero and the simulated rig.

Commands parse arguments and call library functions; heavy imports happen inside
the commands so that ``rig --help`` stays fast.
"""

from __future__ import annotations

import enum
import functools
import logging
import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from cli.object_app import app as object_app
from cli.options import fixed, number
from cli.sensor_app import app as sensor_app
from rig.config import MAX_FORCE_LIMIT_N, MAX_SPEED, TRAVEL_LIMIT
from rig.config.registry import kinds

app = typer.Typer(
    help="Control the tactile-sensing rig: stages, force gauge, camera. "
    "Every command takes --config FILE, or --sim for the built-in simulated rig.",
    no_args_is_help=True,
    add_completion=False,
)
sim_app = typer.Typer(help="The built-in simulated rig (devices on ptys or loopback sockets).", no_args_is_help=True)
app.add_typer(sim_app, name="sim")
protocols_app = typer.Typer(
    help="The protocol library: list protocols, show one's steps, duration and frames.", no_args_is_help=True
)
app.add_typer(protocols_app, name="protocols")
camera_app = typer.Typer(help="The tactile camera: check it before a run.", no_args_is_help=True)
app.add_typer(camera_app, name="camera")
app.add_typer(sensor_app, name="sensor")
app.add_typer(object_app, name="object")

ConfigOpt = Annotated[
    Optional[Path],
    typer.Option("--config", "-c", help="Rig config TOML (default: $RIG_CONFIG, then ./rig.toml).", dir_okay=False),
]
SimOpt = Annotated[bool, typer.Option("--sim", help="Use the built-in simulated rig instead of hardware.")]


def _known_object(name: str | None) -> str | None:
    """--object: a library object's name or an object file that exists; BadParameter otherwise."""
    if name is None:
        return None
    from objects.indenters import INDENTERS
    from objects.object_file import is_object_file

    if name in INDENTERS or (is_object_file(name) and Path(name).is_file()):
        return name
    raise typer.BadParameter(
        f"{name!r} is neither a library object ({', '.join(INDENTERS)}) nor an object file (.toml) that exists"
    )


ObjectOpt = Annotated[
    Optional[str],
    typer.Option(
        "--object",
        callback=_known_object,
        help="The indenter now mounted (a library object or object file name): the rig remembers a gel surface per "
        "indenter, so a different one descends at the in-contact speed until it sees the gel (default: the one "
        "named last).",
    ),
]
ProfileOpt = Annotated[
    Optional[Path],
    typer.Option(
        help="With --sim: the simulated sensor's profile TOML (`rig sensor calibrate` writes one; default: the "
        "shipped GelSight Mini).",
        dir_okay=False,
    ),
]


class AxisName(str, enum.Enum):
    x = "x"
    y = "y"
    z = "z"
    theta = "theta"


class Transport(str, enum.Enum):
    pty = "pty"
    tcp = "tcp"


# The gauges the simulated rig can stand in: the registry rows with a simulator.
GaugeKind = enum.Enum(  # type: ignore[misc]  # members come from the registry, so mypy cannot list them
    "GaugeKind", [(name, name) for name in kinds("gauge", simulated=True)], type=str
)


def _fail(message: str, code: int = 1):
    typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
    raise typer.Exit(code)


def friendly_errors(fn):
    """Every failure becomes one red line and a non-zero exit, never a traceback: rig
    errors and bad input exit 1; a signal exits 128 + its number (Ctrl-C 130, SIGTERM
    143, SIGHUP 129) after the motion session stopped everything."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from common.errors import ToolError
        from rig.interruption import MotionInterrupted

        try:
            return fn(*args, **kwargs)
        except (typer.Exit, typer.Abort, typer.TyperException):
            raise  # typer's own ways out (a command's exit code, a bad option)
        except ToolError as exc:
            _fail(str(exc))
        except (FileNotFoundError, ValueError) as exc:
            _fail(str(exc))
        except MotionInterrupted as exc:
            typer.secho(
                f"interrupted ({exc.signal_name}): motion stopped, devices closed", fg=typer.colors.YELLOW, err=True
            )
            raise typer.Exit(exc.exit_code) from None
        except KeyboardInterrupt:
            typer.secho("interrupted: motion stopped, devices closed", fg=typer.colors.YELLOW, err=True)
            raise typer.Exit(130) from None
        except Exception as exc:  # a driver's or the OS's error: still one line, naming its type
            logging.getLogger("rig").debug("unexpected error", exc_info=True)
            _fail(f"{type(exc).__name__}: {exc}")

    return wrapper


def _say(text: str) -> None:
    """Progress on stderr (stdout keeps only the result): a long move shows it started."""
    typer.echo(f"{text} (Ctrl-C stops)", err=True)


def _note(text: str) -> None:
    """What the speed envelope or the depth guard changed about a move, on stderr."""
    typer.secho(f"note: {text}", fg=typer.colors.YELLOW, err=True)


@app.command()
@friendly_errors
def status(config: ConfigOpt = None, sim: SimOpt = False, profile: ProfileOpt = None):
    """Print every axis (position, state, homed, warnings), the gauge and the current wrench, and the
    camera when configured (resolution, fps, exposure and white balance locked, age of the newest frame)."""
    from cli.session import open_rig
    from cli.views import print_status

    with open_rig(config, sim, profile=profile, camera=None) as rig:
        print_status(rig)


@app.command()
@friendly_errors
def jog(
    axis: Annotated[AxisName, typer.Option("--axis", "-a", help="Axis to move: x, y, z (mm) or theta (deg).")],
    step: Annotated[
        Optional[float],
        typer.Option(
            help="Move by this much (mm, or deg for theta) and exit (default: interactive jogging).",
            callback=number(low=-TRAVEL_LIMIT, high=TRAVEL_LIMIT),
        ),
    ] = None,
    to: Annotated[
        Optional[float],
        typer.Option(
            help="Move to this absolute position (mm or deg) and exit (default: interactive jogging).",
            callback=number(low=-TRAVEL_LIMIT, high=TRAVEL_LIMIT),
        ),
    ] = None,
    speed: Annotated[
        Optional[float],
        typer.Option(
            help="Speed in mm/s (deg/s for theta); default: the axis's jog_speed from the config.",
            callback=number(positive=True, high=MAX_SPEED),
        ),
    ] = None,
    key_step: Annotated[
        float,
        typer.Option(
            help="Interactive mode: initial step per keypress (mm or deg); [ and ] divide/multiply it by 10.",
            min=0.0001,
            callback=number(positive=True, high=TRAVEL_LIMIT),
        ),
    ] = 0.1,
    pendant: Annotated[bool, typer.Option(help="Interactive mode: jog with the HID pendant (SpaceMouse).")] = False,
    allow_deep: Annotated[
        bool,
        typer.Option(
            "--allow-deep",
            help="Let z go below the depth guard's floor (a fraction of the gel thickness under the gel surface), "
            "at the slow speed the window behind the gel allows (docs/safety.md).",
        ),
    ] = False,
    indenter: ObjectOpt = None,
    config: ConfigOpt = None,
    sim: SimOpt = False,
    profile: ProfileOpt = None,
):
    """Jog one axis: by --step, to --to, or interactively (keys + and - or arrows; q quits).
    Speeds above the speed envelope are clamped, with a line saying why (docs/safety.md)."""
    from cli.session import has_z, open_rig

    if step is not None and to is not None:
        _fail("give --step or --to, not both")
    if step is None and to is None and not pendant and not stdin_is_terminal():
        _fail("interactive jogging needs a terminal (stdin is not one): run it in a terminal, or give --step or --to")
    # z opens too: a signal or an error while x, y or theta presses sideways still lifts it
    axes = (axis.value, "z") if axis.value != "z" and has_z(config, sim) else (axis.value,)
    with open_rig(config, sim, profile=profile, axes=axes, indenter=indenter) as rig:
        unit = rig.config.axes[axis.value].unit
        if step is not None or to is not None:
            with rig.motion("jog", on_start=_say, on_note=_note, allow_deep=allow_deep) as m:
                final = m.jog(axis.value, step=step, to=to, speed=speed)
            typer.echo(f"{axis.value} = {fixed(final, 4, sign=False)} {unit}")
            return
        from cli.interactive import jog_with_keys, jog_with_pendant

        with rig.motion("jog", on_note=_note, allow_deep=allow_deep) as m:
            if pendant:
                jog_with_pendant(m, axis.value, key_step, speed)
            else:
                jog_with_keys(m, axis.value, key_step, speed)


def stdin_is_terminal() -> bool:
    """Interactive jogging reads single keys from a terminal (tests stand one in here)."""
    import sys

    return sys.stdin.isatty()


@app.command()
@friendly_errors
def home(
    axis: Annotated[
        Optional[list[AxisName]],
        typer.Option("--axis", "-a", help="Axis to home (repeatable); default all. z always goes first."),
    ] = None,
    config: ConfigOpt = None,
    sim: SimOpt = False,
    profile: ProfileOpt = None,
):
    """Home axes (z first, so the indenter lifts clear before anything slides)."""
    from cli.session import open_rig

    names = tuple(a.value for a in axis) if axis else None
    with open_rig(config, sim, profile=profile, axes=names) as rig:
        with rig.motion("home", on_start=_say) as m:
            m.home_axes(names)
        for name, pos in rig.positions().items():
            typer.echo(f"{name} homed, at {fixed(pos, 4, sign=False)} {rig.config.axes[name].unit}")


@app.command()
@friendly_errors
def zero(
    samples: Annotated[int, typer.Option(help="Samples averaged for the tare.", min=1, max=10000)] = 50,
    config: ConfigOpt = None,
    sim: SimOpt = False,
    profile: ProfileOpt = None,
):
    """Tare the force gauge: average unloaded samples, print the bias removed (N, N·mm) and
    remember it for this rig (refused while z is below the remembered gel surface)."""
    from cli.session import has_z, open_rig
    from rig.contact_state import CLEARANCE_MM
    from rig.types import WRENCH_COMPONENTS, WRENCH_UNITS

    with open_rig(config, sim, profile=profile, axes=("z",) if has_z(config, sim) else ()) as rig:
        guard = rig.depth_guard()
        if guard is not None and "z" in rig.axes:
            z = rig.axes["z"].position()
            if z < guard.surface_z + CLEARANCE_MM:
                _fail(
                    f"z = {z:.3f} mm is not clear of the gel surface at z = {guard.surface_z:.3f} mm ({guard.how}): "
                    "a tare now would count the indenter's load as zero; lift z above "
                    f"{guard.surface_z + CLEARANCE_MM:.3f} mm first"
                )
        bias = rig.tare(samples)
        typer.echo(
            "bias removed: "
            + ", ".join(f"{c} {fixed(v, 4)} {u}" for c, v, u in zip(WRENCH_COMPONENTS, bias, WRENCH_UNITS))
        )
        where = rig.state.path or "this process only (the built-in simulated rig is new each command)"
        typer.echo(
            f"remembered as the unloaded reading in {where}: a later command that is interrupted while pressed "
            "judges contact by it (docs/safety.md); acquisition tares again at its start"
        )


@app.command("find-contact")
@friendly_errors
def find_contact_cmd(
    threshold: Annotated[
        float,
        typer.Option(
            "--threshold-n",
            help="|Fz| that counts as touching, N.",
            min=0.001,
            callback=number(positive=True, high=MAX_FORCE_LIMIT_N),
        ),
    ] = 0.05,
    speed: Annotated[
        float,
        typer.Option(
            help="Descent speed of the first pass, mm/s (the second is 10x slower).",
            min=0.001,
            callback=number(positive=True, high=MAX_SPEED),
        ),
    ] = 0.5,
    max_travel: Annotated[
        float,
        typer.Option(
            help="How far down to search from the present z, mm.",
            min=0.01,
            callback=number(positive=True, high=TRAVEL_LIMIT),
        ),
    ] = 10.0,
    set_origin: Annotated[
        bool,
        typer.Option(
            "--set-origin",
            help="Also remember the contact point (x, y, z, theta) for this rig: rig run-protocol starts from it "
            "when --origin is not given.",
        ),
    ] = False,
    indenter: ObjectOpt = None,
    config: ConfigOpt = None,
    sim: SimOpt = False,
    profile: ProfileOpt = None,
):
    """Lower z under the force limits until the indenter touches the gel; print the contact point as a
    complete --origin x,y,z,theta (x, y and theta where they stand: centre the indenter first, rig check-axes
    says how). The surface is remembered for the indenter mounted (--object)."""
    from cli.session import open_rig
    from rig.contact_search import find_contact

    with open_rig(config, sim, profile=profile, indenter=indenter) as rig:
        found = find_contact(rig, threshold_N=threshold, speed_mm_s=speed, max_travel_mm=max_travel, on_start=_say)
        values, missing = found.origin()
        forgotten = rig.state.forget_origin()
        stored = rig.state.remember_origin(values) if set_origin else None
        where = rig.state.path
    typer.echo(
        f"contact at z = {found.z_mm:.4f} mm (|Fz| = {abs(found.fz_N):.3f} N, resolution "
        f"{found.resolution_mm * 1000:.1f} µm); z lifted clear; remembered as the gel surface for the depth guard"
    )
    origin = ",".join(fixed(v, 4, sign=False) for v in values)
    typer.echo(f"origin: x,y,z,theta = {origin}" + (f" ({', '.join(missing)} not configured: 0)" if missing else ""))
    if forgotten is not None and (stored is None or forgotten.values != stored.values):
        typer.echo(
            f"the origin remembered before ({forgotten.text()}) is replaced by this contact"
            if stored
            else f"the origin remembered before ({forgotten.text()}) was forgotten: it predates this contact"
        )
    if stored is None:
        typer.echo(f"use: rig run-protocol NAME --origin {origin}   (or rig find-contact --set-origin to store it)")
    elif where is None:
        typer.echo(
            "origin stored for this process only: the built-in simulated rig is new each command, and its contact "
            "point is 0,0,0,0 (rig run-protocol --sim starts there)"
        )
    else:
        typer.echo(f"origin stored in {where}: rig run-protocol NAME starts from it when --origin is not given")


@app.command("check-axes")
@friendly_errors
def check_axes_cmd(
    fix: Annotated[
        bool,
        typer.Option(
            "--fix",
            help="Write the fix (which stage is x and which y, each axis's direction) into the rig config, "
            "atomically, keeping a copy of the old file beside it.",
        ),
    ] = False,
    step: Annotated[
        float,
        typer.Option("--step-mm", help="How far x and y move each way, mm.", callback=number(positive=True, high=5.0)),
    ] = 1.0,
    twist: Annotated[
        float,
        typer.Option(
            "--twist-deg",
            help="How far theta turns each way while pressed, deg.",
            callback=number(positive=True, high=45.0),
        ),
    ] = 5.0,
    depth: Annotated[
        Optional[float],
        typer.Option(
            "--depth-mm",
            help="How deep to press below the gel surface, mm "
            "(default: a third of the config's safety.gel_thickness_mm).",
            callback=number(positive=True, high=TRAVEL_LIMIT),
        ),
    ] = None,
    config: ConfigOpt = None,
    sim: SimOpt = False,
    profile: ProfileOpt = None,
):
    """Check that +x moves the contact right in the camera image, +y up and +theta counter-clockwise (the run
    files' convention), and that the gauge's Fx, Fy agree: small guarded presses and moves with the indenter on the
    gel. Reports mirrored, swapped or turned axes, the mm per pixel seen, and where the contact sits in the frame
    (the move that centres it). With --fix, writes the config change. Exit 2 when the axes disagree."""
    from cli.axis_check_cmd import run_check
    from rig.axis_check import CheckSettings

    ok = run_check(
        config=config,
        sim=sim,
        profile=profile,
        fix=fix,
        settings=CheckSettings(step_mm=step, twist_deg=twist, depth_mm=depth),
        say=_say,
        note=_note,
        out=typer.echo,
        warn=lambda text: typer.secho(text, fg=typer.colors.YELLOW),
    )
    if not ok:
        raise typer.Exit(2)


IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


@camera_app.command("snapshot")
@friendly_errors
def camera_snapshot(
    out: Annotated[
        Path,
        typer.Option(help=f"The image to write ({', '.join(IMAGE_SUFFIXES)}); replaced if it exists.", dir_okay=False),
    ] = Path("frame.png"),
    config: ConfigOpt = None,
    sim: SimOpt = False,
    profile: ProfileOpt = None,
):
    """Grab one frame from the camera and write it to --out; print its size and the camera's settings."""
    import cv2
    from rich.console import Console

    from cli.session import open_rig
    from cli.views import print_camera

    if out.suffix.lower() not in IMAGE_SUFFIXES:
        raise typer.BadParameter(
            f"must end in one of {', '.join(IMAGE_SUFFIXES)}, got {str(out)!r}", param_hint="'--out'"
        )
    if not out.parent.is_dir():
        _fail(f"--out: folder {out.parent} does not exist")
    with open_rig(config, sim, profile=profile, axes=(), gauge=False, camera=True) as rig:
        report = rig.camera.report()
        rig.camera.trigger()
        frame = rig.camera.read(timeout_s=2.0)
        print_camera(rig.config.camera, report, Console(stderr=True))
    if not cv2.imwrite(str(out), frame.image):
        _fail(f"--out: cannot write {out}")
    typer.echo(f"{out}: {frame.image.shape[1]}x{frame.image.shape[0]} frame")


@sim_app.command("serve")
@friendly_errors
def sim_serve(
    out: Annotated[Path, typer.Option(help="Where to write the rig config that points at the simulators.")] = Path(
        "rig-sim.toml"
    ),
    transport: Annotated[
        Transport, typer.Option(help="pty (virtual serial ports) or tcp (socket:// on 127.0.0.1).")
    ] = Transport.pty,
    gauge: Annotated[GaugeKind, typer.Option(help="Which force gauge to simulate.")] = GaugeKind("ft300"),
    gauge_rate_hz: Annotated[
        float,
        typer.Option(help="The simulated gauge's sample rate, Hz.", callback=number(positive=True, high=2000.0)),
    ] = 100.0,
    indenter: Annotated[
        str, typer.Option("--object", help="The indenter the simulated rig carries.", callback=_known_object)
    ] = "sphere10mm",
    profile: ProfileOpt = None,
):
    """Start the simulated rig, print its port URLs, write a config; runs until Ctrl-C.
    Refused while another `rig sim serve` writes the same --out."""
    import faulthandler
    import os
    import signal
    import threading

    faulthandler.register(signal.SIGUSR1)  # `kill -USR1 PID` prints every thread's stack (a stuck simulator)

    from cli.session import load_sim_profile
    from rig.interruption import SignalsAsExceptions
    from rig.ownership import claim
    from rig.sim.rig_sim import SERVED_DEVICE_TIMEOUT_S, SimulatedRig

    sensor_profile = load_sim_profile(profile)
    with (
        claim({os.path.realpath(out): ["rig sim serve --out"]}, subject="config"),
        SimulatedRig(
            transport=transport.value,
            gauge=gauge.value,
            profile=sensor_profile,
            gauge_rate_hz=gauge_rate_hz,
            indenter=indenter,
        ) as simulated,
    ):
        camera = simulated.serve_camera()
        written = "# Written by `rig sim serve`; valid while that process runs (removed when it stops).\n" + (
            simulated.config_toml(device_timeout_s=SERVED_DEVICE_TIMEOUT_S)
        )
        try:
            with SignalsAsExceptions():  # SIGTERM and SIGHUP too: the config is removed either way
                out.write_text(written)
                for name, server in simulated.servers.items():
                    typer.echo(f"{name:7s} {server.url}")
                typer.echo(f"{'camera':7s} {camera.url}")
                typer.echo(f"{'sensor':7s} {sensor_profile.name} ({sensor_profile.path})")
                typer.echo(f"{'object':7s} {indenter}; gauge at {gauge_rate_hz:g} Hz")
                typer.echo(f"config  {out}   (try: rig status --config {out})")
                typer.echo("serving; Ctrl-C stops")
                threading.Event().wait()
        except KeyboardInterrupt as exc:
            typer.echo(f"stopped ({getattr(exc, 'signal_name', 'SIGINT')})")
        finally:
            _remove_if_ours(out, written)


def _remove_if_ours(path: Path, written: str) -> None:
    """Remove the config `rig sim serve` wrote, unless someone changed it since (then it is theirs)."""
    try:
        if path.read_text() == written:
            path.unlink()
            typer.echo(f"removed {path}")
        else:
            typer.echo(f"left {path} in place: it was changed after `rig sim serve` wrote it")
    except OSError:
        pass  # already gone, or unreadable: nothing of ours to remove


@protocols_app.command("list")
@friendly_errors
def protocols_list():
    """List the library's protocols with their duration and frame count."""
    from cli.protocol_cmds import list_protocols

    list_protocols()


SetOpt = Annotated[
    Optional[list[str]],
    typer.Option(
        "--set",
        help="Change one protocol key for this run, as section.key=value (repeatable), e.g. "
        "--set motion.speed_mm_s=0.1 (the paper's ~700 frames per object) or --set protocol.sensor=rgb_markers. "
        "The run file stores the changed protocol. Default: the protocol as written.",
    ),
]


@protocols_app.command("show")
@friendly_errors
def protocols_show(
    name: Annotated[str, typer.Argument(help="A library protocol name, or a path to a .toml file.")],
    settings: SetOpt = None,
):
    """Print a protocol's steps, its true duration, frame count and disk estimate."""
    from cli.protocol_cmds import show_protocol

    show_protocol(name, settings=settings or [])


def _origin(value: str) -> tuple[float, float, float, float]:
    try:
        parts = tuple(float(v) for v in value.split(","))
    except ValueError:
        raise typer.BadParameter(f"expected four numbers x,y,z,theta, got {value!r}") from None
    if len(parts) != 4 or not all(math.isfinite(p) for p in parts):
        raise typer.BadParameter(f"'--origin' expects four finite numbers x,y,z,theta, got {value!r}")
    return parts


@app.command("run-protocol")
@friendly_errors
def run_protocol_cmd(
    name: Annotated[str, typer.Argument(help="A library protocol (rig protocols list), or a path to a .toml file.")],
    out: Annotated[
        Optional[Path],
        typer.Option(help="The HDF5 run file to write; must not exist (default: runs/NAME-YYYYmmdd-HHMMSS.h5)."),
    ] = None,
    resume: Annotated[
        Optional[Path], typer.Option(help="Continue this interrupted run file where it stopped (default: a new run).")
    ] = None,
    dry_run: Annotated[
        bool,
        typer.Option(
            "--dry-run",
            help="Check every move against the config's limits and print duration and frame count; move nothing.",
        ),
    ] = False,
    origin: Annotated[
        Optional[str],
        typer.Option(
            help="The contact point in axis coordinates: x,y,z (mm),theta (deg). Default: the origin rig "
            "find-contact --set-origin remembered for this rig, else 0,0,0,0 (the simulated rig's contact point); "
            "the run says which it used."
        ),
    ] = None,
    settings: SetOpt = None,
    config: ConfigOpt = None,
    sim: SimOpt = False,
    profile: ProfileOpt = None,
):
    """Run a protocol with synchronised capture (frame + wrench + pose at the protocol's rate) into HDF5.

    With --sim the simulated rig runs on simulated time, as fast as the frames can be made.
    """
    from cli.protocol_cmds import run_protocol

    run_protocol(
        name,
        out=out,
        resume=resume,
        dry_run=dry_run,
        config=config,
        sim=sim,
        origin=_origin(origin) if origin is not None else None,
        settings=settings or [],
        profile=profile,
    )


@app.command("console")
@friendly_errors
def console_cmd(
    host: Annotated[
        str,
        typer.Option(help="Address to listen on; any other than 127.0.0.1 needs the access token printed at start."),
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port (0: any free port).", min=0, max=65535)] = 8765,
    runs: Annotated[
        Path, typer.Option(help="Folder whose *.h5 run files the run browser lists.", file_okay=False)
    ] = Path("runs"),
    config: ConfigOpt = None,
    sim: SimOpt = False,
    sensor: Annotated[
        str,
        typer.Option(
            help="The camera's sensor kind: rgb, rgb_markers or white_markers; marker kinds get marker-flow "
            "arrows (with --sim, the kind the simulated camera renders)."
        ),
    ] = "rgb",
):
    """Serve the web console: live tactile frame, marker flow, wrench traces, axes, guarded jog/stop/home/zero,
    run browser and the progress of protocol runs being written."""
    from cli.console.launch import run_console

    run_console(config=config, sim=sim, live=True, host=host, port=port, runs=[runs], say=typer.echo, sensor=sensor)


if __name__ == "__main__":
    app()
