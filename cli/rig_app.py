"""``rig``: status, jog, home, zero, find-contact, check-axes, run-protocol and the console.

Commands parse arguments and call library functions; heavy imports happen inside
the commands so that ``rig --help`` stays fast. The sub-apps are in their own files:
``rig sim`` (cli/sim_cmd.py), ``rig protocols`` with ``rig run-protocol`` (cli/protocols_app.py),
``rig camera`` (cli/camera_cmd.py), ``rig sensor`` and ``rig object``; what the commands share
(--config, --sim, one-line failures) is cli/rig_options.py.
"""

from __future__ import annotations

import enum
from pathlib import Path
from typing import Annotated, Optional

import typer

from cli.camera_cmd import app as camera_app
from cli.object_app import app as object_app
from cli.options import fixed, number
from cli.protocols_app import app as protocols_app
from cli.protocols_app import run_protocol_cmd
from cli.rig_options import ConfigOpt, ObjectOpt, ProfileOpt, SimOpt, fail, friendly_errors, note, say
from cli.sensor_app import app as sensor_app
from cli.sim_cmd import app as sim_app
from rig.config import MAX_FORCE_LIMIT_N, MAX_SPEED, TRAVEL_LIMIT

app = typer.Typer(
    help="Control the tactile-sensing rig: stages, force gauge, camera. "
    "Every command takes --config FILE, or --sim for the built-in simulated rig.",
    no_args_is_help=True,
    add_completion=False,
)
app.add_typer(sim_app, name="sim")
app.add_typer(protocols_app, name="protocols")
app.add_typer(camera_app, name="camera")
app.add_typer(sensor_app, name="sensor")
app.add_typer(object_app, name="object")


class AxisName(str, enum.Enum):
    x = "x"
    y = "y"
    z = "z"
    theta = "theta"


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
        fail("give --step or --to, not both")
    if step is None and to is None and not pendant and not stdin_is_terminal():
        fail("interactive jogging needs a terminal (stdin is not one): run it in a terminal, or give --step or --to")
    # z opens too: a signal or an error while x, y or theta presses sideways still lifts it
    axes = (axis.value, "z") if axis.value != "z" and has_z(config, sim) else (axis.value,)
    with open_rig(config, sim, profile=profile, axes=axes, indenter=indenter) as rig:
        unit = rig.config.axes[axis.value].unit
        if step is not None or to is not None:
            with rig.motion("jog", on_start=say, on_note=note, allow_deep=allow_deep) as m:
                final = m.jog(axis.value, step=step, to=to, speed=speed)
            typer.echo(f"{axis.value} = {fixed(final, 4, sign=False)} {unit}")
            return
        from cli.interactive import jog_with_keys, jog_with_pendant

        with rig.motion("jog", on_note=note, allow_deep=allow_deep) as m:
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
        with rig.motion("home", on_start=say) as m:
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
    from rig.contact_setup import tare_clear_of_gel
    from rig.types import WRENCH_COMPONENTS, WRENCH_UNITS

    with open_rig(config, sim, profile=profile, axes=("z",) if has_z(config, sim) else ()) as rig:
        bias = tare_clear_of_gel(rig, samples)  # refused while z may press the gel
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
    from rig.contact_setup import find_origin

    with open_rig(config, sim, profile=profile, indenter=indenter) as rig:
        got = find_origin(
            rig, threshold_N=threshold, speed_mm_s=speed, max_travel_mm=max_travel, set_origin=set_origin, on_start=say
        )
    found, missing, forgotten, stored, where = got.found, got.missing, got.forgotten, got.stored, got.where
    typer.echo(
        f"contact at z = {found.z_mm:.4f} mm (|Fz| = {abs(found.fz_N):.3f} N, resolution "
        f"{found.resolution_mm * 1000:.1f} µm); z lifted clear; remembered as the gel surface for the depth guard"
    )
    origin = ",".join(fixed(v, 4, sign=False) for v in got.values)
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
        say=say,
        note=note,
        out=typer.echo,
        warn=lambda text: typer.secho(text, fg=typer.colors.YELLOW),
    )
    if not ok:
        raise typer.Exit(2)


app.command("run-protocol")(run_protocol_cmd)  # its options: cli/protocols_app.py


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
