"""``rig object check FILE``: validate a user's object file and show its photo and height map.

The format: docs/protocols.md, "Your own objects". Heavy imports happen inside the command
so that ``rig --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from cli.options import number

app = typer.Typer(help="Your own objects: check an object file (photo, scale, axis, height map).", no_args_is_help=True)

SENSOR_FIELD_MM = 14.0  # the simulated sensor's field (sensor_sim SensorGeometry), 256 px across


@app.command()
def check(
    file: Annotated[Path, typer.Argument(help="The object file (.toml) naming the photo and the height map.")],
    out: Annotated[
        Optional[Path],
        typer.Option(
            help="Write the sheet (photo | height map | both) to this PNG (default: none, only the check is printed).",
            dir_okay=False,
        ),
    ] = None,
    size_px: Annotated[int, typer.Option(min=16, max=2048, help="Panel size in pixels (the sensor's frame).")] = 256,
    mm_per_px: Annotated[
        float,
        typer.Option(
            help="The sensor's scale in mm per pixel (default: the simulated sensor, 14 mm over 256 px).",
            callback=number(low=1e-4, high=1.0),
        ),
    ] = SENSOR_FIELD_MM / 256,
):
    """Validate FILE (one line naming the file, the key and the value when something is wrong), print
    the photo's and height map's sizes in mm, and with --out write them side by side at the sensor's scale."""
    from common.errors import ToolError

    try:
        from objects.object_file import load_object_file
        from objects.object_sheet import check_sheet, describe

        obj = load_object_file(file)
        for line in describe(obj, size_px, mm_per_px):
            typer.echo(line)
        if out is not None:
            import cv2

            if not cv2.imwrite(str(out), check_sheet(obj, size_px, mm_per_px)):
                raise ToolError(f"{out}: [--out] cannot write the sheet (a .png in a writable folder?)")
            typer.echo(f"wrote {out}")
    except ToolError as exc:
        typer.secho(f"error: {exc}", fg=typer.colors.RED, err=True)
        raise typer.Exit(1) from None
