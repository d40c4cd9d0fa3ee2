"""``rig camera snapshot``: one frame from the tactile camera written to a file, with the camera's settings."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from cli.rig_options import ConfigOpt, ProfileOpt, SimOpt, fail, friendly_errors

app = typer.Typer(help="The tactile camera: check it before a run.", no_args_is_help=True)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


@app.command("snapshot")
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
        fail(f"--out: folder {out.parent} does not exist")
    with open_rig(config, sim, profile=profile, axes=(), gauge=False, camera=True) as rig:
        report = rig.camera.report()
        rig.camera.trigger()
        frame = rig.camera.read(timeout_s=2.0)
        print_camera(rig.config.camera, report, Console(stderr=True))
    if not cv2.imwrite(str(out), frame.image):
        fail(f"--out: cannot write {out}")
    typer.echo(f"{out}: {frame.image.shape[1]}x{frame.image.shape[0]} frame")
