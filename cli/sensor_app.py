"""``rig sensor calibrate``: a sensor profile from a no-contact frame and a few ball presses.

Parses the options, reads the presses (cli/sensor_inputs.py), fits the optics
(sensor_sim.calibration.fit_optics), prints the error per press beside the background-only
baseline's, writes the profile (TOML + background PNG) and a contact sheet. Heavy imports
(numpy, cv2, scipy) happen inside the command so that ``rig --help`` stays fast.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, NoReturn, Optional

import typer

from cli.options import number

app = typer.Typer(help="The tactile sensor: calibrate the simulator to yours.", no_args_is_help=True)

NAME = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")


def _fail(message: str) -> NoReturn:
    typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
    raise typer.Exit(1)


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
        Optional[float],
        typer.Option(
            help="Side of the square field the simulator renders, in mm (default: the frame's shorter side).",
            callback=number(positive=True, high=1000.0),
        ),
    ] = None,
    frame_px: Annotated[int, typer.Option(help="Side of the simulated frame in pixels.", min=16, max=4096)] = 256,
    gel_thickness_mm: Annotated[
        float, typer.Option(help="Gel thickness in mm.", callback=number(low=0.05, high=50.0))
    ] = 3.0,
    gel_modulus_mpa: Annotated[
        float, typer.Option("--gel-E-MPa", help="Gel Young's modulus in MPa.", callback=number(low=1e-3, high=1e3))
    ] = 0.25,
    noise_std: Annotated[
        Optional[float],
        typer.Option(
            help="Sensor noise, grey levels per pixel (default: estimated from the presses away from the contact).",
            callback=number(low=0.0, high=50.0),
        ),
    ] = None,
):
    """Fit the simulated sensor's optics to your sensor: prints the error per press (MAE 0–255, whole frame
    and within 1.5 contact radii, beside showing the background alone), writes the profile and a contact
    sheet (real | rendered | difference per press). Use the profile with --profile on --sim commands and
    evaluate."""
    import time

    import cv2

    from cli.sensor_inputs import from_folder, from_run
    from common.errors import ToolError
    from sensor_sim.calibration import CalibrationError, fit_optics
    from sensor_sim.calibration_report import contact_sheet, estimate_noise_std, press_scores, profile_from_fit
    from sensor_sim.profile import ProfileError, load_profile, save_profile

    name = name or out.stem
    if not NAME.match(name):
        _fail(f"--name {name!r}: use 1 to 64 letters, digits, '_', '.' or '-'")
    if out.suffix != ".toml":
        _fail(f"--out {out}: expected a file name ending in .toml")
    sheet = sheet or out.with_name(f"{out.stem}-sheet.png")
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
        fit = fit_optics(inputs.background, inputs.presses, scale)
        fit_s = time.perf_counter() - t0
        scores = press_scores(inputs.background, inputs.presses, fit, scale)
        noise = (
            noise_std if noise_std is not None else estimate_noise_std(inputs.background, inputs.presses, fit.contacts)
        )
        profile = profile_from_fit(
            inputs.background,
            fit,
            scale,
            name=name,
            source=f"rig sensor calibrate: {inputs.source}".replace('"', "'"),
            frame_px=frame_px,
            field_mm=field_mm,
            gel_thickness_mm=gel_thickness_mm,
            gel_E_MPa=gel_modulus_mpa,
            noise_std=noise,
        )
        out.parent.mkdir(parents=True, exist_ok=True)
        written = save_profile(profile, out)
        load_profile(written)  # what was written is what every command will read
        if not cv2.imwrite(str(sheet), contact_sheet(inputs.background, inputs.presses, fit, scale)):
            _fail(f"--sheet {sheet}: cannot write the image")
    except (CalibrationError, ProfileError, ToolError, ValueError, OSError) as exc:  # a bad run file: RunFileError
        _fail(str(exc))
    typer.echo(f"fitted {len(scores)} presses in {fit_s:.1f} s: blur {fit.light.blur_mm:g} mm, noise {noise:g}")
    typer.echo("")
    typer.echo("| press | centre x, y px | radius px | fit MAE whole / near | background MAE whole / near |")
    typer.echo("|---|---|---|---|---|")
    for s in scores:
        typer.echo(
            f"| {s.name} | {s.contact.centre_x_px:.1f}, {s.contact.centre_y_px:.1f} | {s.contact.radius_px:.1f} | "
            f"{s.mae:.2f} / {s.mae_near:.2f} | {s.background_mae:.2f} / {s.background_mae_near:.2f} |"
        )
    mean = [sum(getattr(s, k) for s in scores) / len(scores) for k in ("mae", "mae_near")]
    base = [sum(getattr(s, k) for s in scores) / len(scores) for k in ("background_mae", "background_mae_near")]
    typer.echo(f"| **mean** | | | **{mean[0]:.2f} / {mean[1]:.2f}** | **{base[0]:.2f} / {base[1]:.2f}** |")
    typer.echo("")
    typer.echo(f"near the contact: {mean[1] / base[1]:.0%} of the background-only error (in-sample)")
    worse = [s.name for s in scores if s.mae_near >= s.background_mae_near]
    if worse:
        typer.secho(
            f"warning: no better than the background near the contact on {', '.join(worse)}: check the contact "
            "sheet, the ball radius and --mm-per-px",
            fg=typer.colors.YELLOW,
        )
    typer.echo(
        f"profile: {written} (+ {written.with_suffix('.png').name}), {profile.width_px} px over "
        f"{profile.width_px * profile.mm_per_px:.2f} mm"
    )
    typer.echo(f"contact sheet: {sheet}")
    typer.echo(
        f"use it: rig run-protocol sphere4mm --sim --profile {written}   (total {time.perf_counter() - t0:.1f} s)"
    )
