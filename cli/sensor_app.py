"""``rig sensor``: calibrate the simulator to your sensor, and render a press through a profile.

``calibrate`` parses the options, reads the presses (cli/sensor_inputs.py), fits the optics
(sensor_sim.calibration.fit_optics), prints the error per press beside the background-only
baseline's, where the field lacks presses and any parameter pinned at a bound, writes the
profile (TOML + background PNG) and a contact sheet. ``render`` draws one frame of an object at
a pose through a profile (sensor_sim.press_render: the simulated rig's contact solver and
renderer). Heavy imports (numpy, cv2, scipy) happen inside the commands so that ``rig --help``
stays fast.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, NoReturn, Optional

import typer

from cli.options import number

app = typer.Typer(
    help="The tactile sensor: calibrate the simulator to yours, render a press through a profile.",
    no_args_is_help=True,
)

NAME = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")
POSE_LIMITS = ((100.0, "mm"), (100.0, "mm"), (50.0, "mm"), (360.0, "deg"))
WRENCH_LIMITS = ((1000.0, "N"),) * 3 + ((1e5, "N·mm"),) * 3


def _fail(message: str) -> NoReturn:
    typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
    raise typer.Exit(1)


def _numbers(option: str, text: str, limits: tuple[tuple[float, str], ...], names: str) -> tuple[float, ...]:
    """``len(limits)`` finite comma-separated numbers within ±their limits, or a one-line error."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise typer.BadParameter(f"{option}: expected {names} as numbers, got {text!r}") from None
    if len(values) != len(limits):
        raise typer.BadParameter(f"{option}: expected {len(limits)} values {names}, got {len(values)} in {text!r}")
    for name, value, (bound, unit) in zip(names.split(","), values, limits):
        if not math.isfinite(value) or abs(value) > bound:
            raise typer.BadParameter(
                f"{option}: {name} is {value:g}; expected a finite number within ±{bound:g} {unit}"
            )
    return values


def _field(text: str | None) -> tuple[float, float] | None:
    """``--field-mm``: "W,H" or one number (a square), positive mm."""
    if text is None:
        return None
    parts = text.split(",")
    values = _numbers("--field-mm", text, ((1000.0, "mm"),) * len(parts), ",".join(["width", "height"][: len(parts)]))
    if len(values) not in (1, 2) or min(values) <= 0:
        raise typer.BadParameter(f"--field-mm: expected a width and height in mm (or one side), > 0, got {text!r}")
    return (values[0], values[-1])


@app.command("calibrate")
def calibrate(
    source: Annotated[
        Path,
        typer.Argument(
            help="A folder with background.png and press PNGs (optionally presses.csv), or a run file (.h5) "
            "recorded with a sphere."
        ),
    ],
    out: Annotated[
        Path, typer.Option(help="The profile TOML to write; its background PNG goes beside it (same stem).")
    ] = Path("sensor.toml"),
    ball_radius_mm: Annotated[
        Optional[float],
        typer.Option(
            help="Radius of the pressed ball in mm. Default: a run file's sphere; a folder needs it unless its CSV "
            "has ball_radius_mm.",
            callback=number(positive=True, high=100.0),
        ),
    ] = None,
    mm_per_px: Annotated[
        Optional[float],
        typer.Option(
            help="Scale of the frames in mm per pixel. Default: a run file's mm_per_px; a folder needs it.",
            callback=number(positive=True, high=1.0),
        ),
    ] = None,
    background: Annotated[
        Optional[Path], typer.Option(help="The no-contact frame (default: SOURCE/background.png).", dir_okay=False)
    ] = None,
    csv_file: Annotated[
        Optional[Path],
        typer.Option(
            "--csv",
            help="Presses to use: a CSV with a file column and optional centre_x_px, centre_y_px, radius_px "
            "(manual contact), depth_mm, ball_radius_mm (default: SOURCE/presses.csv if there, else every PNG).",
            dir_okay=False,
        ),
    ] = None,
    presses: Annotated[
        int, typer.Option(help="From a run file: how many press frames, spread over depth.", min=1, max=50)
    ] = 5,
    name: Annotated[
        Optional[str], typer.Option(help="The profile's name (letters, digits, _.-; default: --out's stem).")
    ] = None,
    sheet: Annotated[
        Optional[Path], typer.Option(help="The contact sheet PNG (default: beside --out, STEM-sheet.png).")
    ] = None,
    field_mm: Annotated[
        Optional[str],
        typer.Option(
            help="The field the simulator renders, centred: WIDTH,HEIGHT in mm, or one number for a square "
            "(default: the whole frame)."
        ),
    ] = None,
    frame_px: Annotated[
        Optional[int],
        typer.Option(
            help="Width of the simulated frame in pixels; its height keeps the field's aspect (default: the "
            "camera's own pixels).",
            min=16,
            max=4096,
        ),
    ] = None,
    gel_thickness_mm: Annotated[
        float, typer.Option(help="Gel thickness in mm.", callback=number(low=0.05, high=50.0))
    ] = 3.0,
    gel_modulus_mpa: Annotated[
        float, typer.Option("--gel-E-MPa", help="Gel Young's modulus in MPa.", callback=number(low=1e-3, high=1e3))
    ] = 0.25,
    noise_std: Annotated[
        Optional[float],
        typer.Option(
            help="Sensor noise, grey levels per pixel, independent (default: measured from the presses away from "
            "the contact: per channel, with its spatial and between-channel correlation).",
            callback=number(low=0.0, high=50.0),
        ),
    ] = None,
):
    """Fit the simulated sensor's optics to your sensor: prints the error per press (MAE 0–255, whole frame
    and within 1.5 contact radii, beside showing the background alone), where the field has no press, writes
    the profile and a contact sheet (real | rendered | difference per press). Use the profile with --profile
    on --sim commands, evaluate and `rig sensor render`."""
    import time

    from cli.one_line import passes_through, unexpected
    from cli.sensor_inputs import from_folder, from_run
    from common.errors import ToolError
    from sensor_sim.calibration import CalibrationError
    from sensor_sim.calibration_job import calibrate as calibrate_presses
    from sensor_sim.calibration_report import mean_scores
    from sensor_sim.elastomer import Elastomer, PhysicsInputError
    from sensor_sim.profile import ProfileError

    name = name or out.stem
    if not NAME.match(name):
        _fail(f"--name {name!r}: use 1 to 64 letters, digits, '_', '.' or '-'")
    if out.suffix != ".toml":
        _fail(f"--out {out}: expected a file name ending in .toml")
    field = _field(field_mm)
    t0 = time.perf_counter()
    try:
        if source.is_dir():
            inputs = from_folder(source, ball_radius_mm, background, csv_file)
        elif source.suffix.lower() in (".h5", ".hdf5"):
            inputs = from_run(source, presses, ball_radius_mm)
        else:
            _fail(f"{source}: expected a folder of PNGs or a run file (.h5)")
        scale = mm_per_px or inputs.mm_per_px
        if scale is None:
            _fail(f"{source}: the frames' scale is unknown: pass --mm-per-px")
        for note in inputs.notes:
            typer.echo(note)
        done = calibrate_presses(
            inputs.background,
            inputs.presses,
            scale,
            Elastomer(E_MPa=gel_modulus_mpa, thickness_mm=gel_thickness_mm),
            out=out,
            sheet=sheet or out.with_name(f"{out.stem}-sheet.png"),
            name=name,
            source=f"rig sensor calibrate: {inputs.source}",
            noise_std=noise_std,
            frame_px=frame_px,
            field_mm=field,
        )
    except (CalibrationError, ProfileError, ToolError, PhysicsInputError, ValueError, OSError) as exc:
        _fail(str(exc))  # a bad run file: RunFileError
    except Exception as exc:  # nothing expected it: still one line, naming its type (cli/one_line.py)
        if passes_through(exc):
            raise
        _fail(unexpected(exc, "sensor"))
    fit, noise, profile = done.fit, done.noise, done.profile
    typer.echo(
        f"fitted {len(done.scores)} presses in {fit.seconds:.1f} s: blur {fit.light.blur_mm:g} mm, light: "
        f"{done.model_words} (chosen by leaving each press out)"
    )
    typer.echo(
        f"noise: std {', '.join(f'{v:g}' for v in noise.std_bgr)} (b, g, r), correlation {noise.correlation_px:g} px, "
        f"between channels {', '.join(f'{v:g}' for v in noise.channel_correlation)}"
    )
    typer.echo("")
    typer.echo("| press | centre x, y px | radius px | depth mm | fit MAE whole / near | background MAE whole / near |")
    typer.echo("|---|---|---|---|---|---|")
    for s in done.scores:
        c = s.contact
        typer.echo(
            f"| {s.name} | {c.centre_x_px:.1f}, {c.centre_y_px:.1f} | {c.radius_px:.1f} | {c.depth_mm or 0:.3f} | "
            f"{s.mae:.2f} / {s.mae_near:.2f} | {s.background_mae:.2f} / {s.background_mae_near:.2f} |"
        )
    mean = mean_scores(done.scores)
    typer.echo(f"| **mean** | | | | **{mean[0]:.2f} / {mean[1]:.2f}** | **{mean[2]:.2f} / {mean[3]:.2f}** |")
    typer.echo("")
    typer.echo(f"near the contact: {mean[1] / mean[3]:.0%} of the background-only error (in-sample)")
    worst = done.worst_left_out
    if worst is not None and done.expected is not None:
        typer.echo(
            f"expected for a press not fitted: {done.expected:.0%} of the background-only error near the contact "
            "(each press left out in turn, rendered at its fitted contact from the light of the others; worst "
            f"{worst.name} {worst.mae_near / worst.background_mae_near:.0%}; a pose commanded without its frame "
            "scores a few points worse)"
        )
    else:
        typer.echo("expected for a press not fitted: not measured (one press: none to leave out; three or more)")
    typer.echo("depth: from each press's contact radius through the contact solver (no force gauge), refined")
    for line in done.coverage.lines(done.expected):
        typer.echo(line)
    for note in done.fit.notes:
        typer.secho(f"note: {note}", fg=typer.colors.YELLOW)
    if done.no_better:
        typer.secho(
            f"warning: no better than the background near the contact on {', '.join(done.no_better)}: check the "
            "contact sheet, the ball radius and --mm-per-px",
            fg=typer.colors.YELLOW,
        )
    typer.echo(
        f"profile: {done.written} (+ {done.written.with_suffix('.png').name}), {profile.width_px}x{profile.height_px} "
        f"px over {profile.width_mm:.2f} x {profile.height_mm:.2f} mm"
    )
    typer.echo(f"contact sheet: {done.sheet}")
    typer.echo(
        f"use it: rig run-protocol sphere4mm --sim --profile {done.written}   (total {time.perf_counter() - t0:.1f} s)"
    )


@app.command("render")
def render(
    object_name: Annotated[
        str,
        typer.Option(
            "--object",
            help="A library object (rig protocols list shows them, e.g. sphere4mm) or an object file "
            "(.toml with a height map).",
        ),
    ],
    pose: Annotated[
        str,
        typer.Option(
            help="x,y,z,theta: mm from the frame's centre (+y towards its top), mm (negative: pressed in), deg."
        ),
    ],
    out: Annotated[Path, typer.Option(help="The frame to write (PNG), at the profile's resolution.")],
    profile: Annotated[
        Optional[Path],
        typer.Option(help="The sensor profile TOML (rig sensor calibrate writes one; default: the shipped one)."),
    ] = None,
    wrench: Annotated[
        Optional[str],
        typer.Option(
            help="Fx,Fy,Fz,Mx,My,Mz (N, N·mm) measured at this pose: for a marker sensor the gel's tangential state "
            "carries its Fx, Fy and Mz (the pose sets the depth; Fz, Mx, My are the solver's). Default: none, the "
            "gel unsheared."
        ),
    ] = None,
    kind: Annotated[str, typer.Option(help="The sensor kind: rgb, rgb_markers or white_markers.")] = "rgb",
    noise: Annotated[bool, typer.Option("--noise/--no-noise", help="Add the profile's camera noise.")] = True,
    seed: Annotated[int, typer.Option(help="The noise's random seed.", min=0)] = 0,
):
    """Render one frame of an object pressed at a pose through a sensor profile, at the sensor's own
    resolution and field of view: the contact solver and renderer of the simulated rig. Prints the wrench
    the solver finds."""
    import time

    import cv2

    from common.errors import ToolError
    from common.sensors import SENSOR_KINDS
    from objects.pose import Pose
    from sensor_sim.elastomer import PhysicsInputError
    from sensor_sim.press_render import PressRender
    from sensor_sim.profile import ProfileError, resolve_profile

    if kind not in SENSOR_KINDS:
        _fail(f"--kind {kind!r}: expected one of {', '.join(SENSOR_KINDS)}")
    if out.suffix.lower() != ".png":
        _fail(f"--out {out}: expected a file name ending in .png")
    try:
        x, y, z, theta = _numbers("--pose", pose, POSE_LIMITS, "x,y,z,theta")
        load = _numbers("--wrench", wrench, WRENCH_LIMITS, "Fx,Fy,Fz,Mx,My,Mz") if wrench is not None else None
    except typer.BadParameter as exc:
        _fail(str(exc))
    t0 = time.perf_counter()
    try:
        sensor = resolve_profile(profile)
        press = PressRender(sensor, object_name, kind, noise=noise, seed=seed)
        result = press.solve(Pose(x, y, z, theta), load)
        frame = press.renderer.render(result.fields)
        out.parent.mkdir(parents=True, exist_ok=True)
        if not cv2.imwrite(str(out), frame):
            _fail(f"--out {out}: cannot write the image")
    except KeyError as exc:  # an unknown library object: the message names the known ones
        _fail(f"--object {object_name!r}: {exc.args[0]}")
    except (ProfileError, ToolError, PhysicsInputError, ValueError, OSError) as exc:
        _fail(str(exc))
    w = result.wrench
    h_px, w_px = frame.shape[:2]
    typer.echo(
        f"sensor {sensor.name} ({sensor.path or 'built in'}): {w_px}x{h_px} px over "
        f"{press.geometry.width_mm:.2f} x {press.geometry.height_mm:.2f} mm, {kind}, noise {'on' if noise else 'off'}"
    )
    state = (
        "in contact" if result.in_contact else ("narrower than a mechanics cell" if result.sub_cell else "no contact")
    )
    typer.echo(
        f"{object_name} at x {x:g} y {y:g} z {z:g} mm, theta {theta:g} deg: {state}; Fz {w[2]:.3f} N, "
        f"Fx {w[0]:.3f} N, Fy {w[1]:.3f} N, Mz {w[5]:.2f} N·mm"
        + ("" if result.converged else " (the solver stopped short of its tolerance)")
    )
    if load is not None and not press.renderer.spec.has_markers:
        typer.echo(
            "the wrench changes nothing in a frame without markers (it sets the gel's shear, which only markers show)"
        )
    typer.echo(f"frame: {out} ({time.perf_counter() - t0:.2f} s)")
