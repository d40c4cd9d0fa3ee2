"""`dataset export` and `dataset import`: run files to and from plain folders and LeRobot datasets
(the work: dataset/interchange.py, dataset/lerobot/); registered on the dataset app by cli/dataset_app.py."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from cli.options import number


def export(
    paths: Annotated[list[Path], typer.Argument(help="Run files, or one split folder (--format lerobot).")],
    out: Annotated[Path, typer.Option(help="A new folder; must not exist.")],
    fmt: Annotated[
        str,
        typer.Option("--format", help="folder (frames/*.png, frames.csv, run.json) or lerobot (LeRobotDataset v3.0)."),
    ] = "folder",
    codec: Annotated[
        str,
        typer.Option(
            help="lerobot: the frames' video codec: lossless (H.264 RGB, qp 0: every pixel kept), av1 (the "
            "ecosystem's default, lossy) or h264 (lossy)."
        ),
    ] = "lossless",
    episode: Annotated[str, typer.Option(help="lerobot: one episode per run, or per press (depth level).")] = "run",
):
    """Export runs: to PNG frames and a CSV of wrenches and poses (one run; for people who don't use HDF5), or
    to a LeRobot dataset (runs or a split's parts as episodes). Every run is verified first and the folder
    appears only once complete."""
    if fmt == "lerobot":
        from dataset.lerobot.export import export_lerobot

        done = export_lerobot(paths, out, codec_name=codec, episode=episode, say=typer.echo)
        typer.echo(export_line(done))
        return
    if fmt != "folder":
        raise typer.BadParameter(f"expected folder or lerobot, got {fmt!r}", param_hint="'--format'")
    if len(paths) != 1:
        raise typer.BadParameter("--format folder exports one run file", param_hint="'PATHS...'")
    from dataset.interchange import export_run

    typer.echo(f"{out}: {export_run(paths[0], out)} frames")


def export_line(done) -> str:
    """What a LeRobot export says when it is done: size, codec and, lossy, the error it added."""
    error = ""
    if done.mse:
        error = f"; lossy: MSE {sum(done.mse) / len(done.mse):.2f} (max {max(done.mse):.2f}) against the run's frames"
    splits = ", ".join(f"{k} {v}" for k, v in done.splits.items())
    return (
        f"{done.out}: {done.frames} frames in {done.episodes} episode(s) from {done.runs} run(s), "
        f"{done.bytes / 1e6:,.1f} MB ({done.video_bytes / 1e6:,.1f} MB video, {done.codec}){error}; "
        f"splits: {splits}; {done.seconds:.1f} s"
    )


def _mm_per_px(ctx: typer.Context, param: typer.CallbackParam, value: Optional[float]):
    """--mm-per-px: finite and in the import's calibration range, the option named (cli/options.py)."""
    from dataset.interchange import MM_PER_PX

    return number(low=MM_PER_PX[0], high=MM_PER_PX[1])(ctx, param, value)


def _sensor(ctx: typer.Context, param: typer.CallbackParam, value: Optional[str]):
    """--sensor: one of the sensor kinds (common/sensors.py), the choices named."""
    from common.sensors import SENSOR_KINDS

    if value is not None and value not in SENSOR_KINDS:
        problem = f"must be one of {', '.join(SENSOR_KINDS)}, got {value!r}"
        # typer hands callbacks the click parameter it annotates with its private class (cli/options.py)
        raise typer.BadParameter(problem, ctx=ctx, param=param)  # type: ignore[arg-type]
    return value


def import_(
    folder: Annotated[
        Path, typer.Argument(help="A folder in the export format, or a LeRobot dataset (docs/dataset.md).")
    ],
    out: Annotated[Path, typer.Option(help="The run file to write; must not exist.")],
    mm_per_px: Annotated[
        Optional[float],
        typer.Option(help="Frame calibration, mm per pixel (default: run.json's); 0.0001 to 10.", callback=_mm_per_px),
    ] = None,
    object_name: Annotated[Optional[str], typer.Option("--object", help="Object name (default: run.json's).")] = None,
    sensor: Annotated[
        Optional[str],
        typer.Option(
            help="Sensor kind: rgb, rgb_markers or white_markers (default: run.json's; one of them is required).",
            callback=_sensor,
        ),
    ] = None,
    profile: Annotated[
        Optional[Path],
        typer.Option(
            help="The sensor's profile TOML (rig sensor calibrate); recorded in the run file like a run's. "
            "Default: the run file says it has none (physics renders of it then need --profile)."
        ),
    ] = None,
    crop: Annotated[bool, typer.Option("--crop", help="Non-square images: keep the centre square.")] = False,
    pad: Annotated[
        bool, typer.Option("--pad", help="Non-square images: centre them in a square filled with their edge colour.")
    ] = False,
    size: Annotated[
        Optional[int],
        typer.Option(
            help="Resize the square images to N x N px (mm per pixel scaled to match). Default: keep their size.",
            min=16,
            max=4096,
        ),
    ] = None,
    fmt: Annotated[
        str, typer.Option("--format", help="folder (frames.csv + PNG) or lerobot (LeRobotDataset v3.0).")
    ] = "folder",
    camera: Annotated[
        Optional[str],
        typer.Option(
            help="lerobot from elsewhere: the tactile camera's feature. Default: its only video feature, or the one "
            "named tactile, gelsight or digit."
        ),
    ] = None,
    wrench_key: Annotated[
        Optional[str],
        typer.Option(help="lerobot from elsewhere: the six-value wrench feature (default: observation.wrench)."),
    ] = None,
    pose_key: Annotated[
        Optional[str],
        typer.Option(help="lerobot from elsewhere: the four-value pose feature (default: observation.state)."),
    ] = None,
    object_image: Annotated[
        Optional[Path],
        typer.Option(
            help="lerobot from elsewhere: the object's contact-face image (PNG) at pose 0; required there (no default)."
        ),
    ] = None,
    ignore_columns: Annotated[
        Optional[str],
        typer.Option(
            help="frames.csv columns to leave out, comma-separated (any other column the format does not know is "
            "refused). Default: none."
        ),
    ] = None,
):
    """Import tactile PNGs, a CSV of wrenches and poses and an object image from another rig.

    run.json states the pose convention (docs/dataset.md, "Pose convention"); a y-down folder is
    converted. Non-square frames or object images need --crop or --pad."""
    if fmt == "lerobot":
        from dataset.lerobot.import_run import import_lerobot

        foreign: dict[str, object] = dict(
            camera=camera, wrench_key=wrench_key, pose_key=pose_key, object_image=object_image
        )
        foreign.update(mm_per_px=mm_per_px, sensor=sensor, object_name=object_name)
        written = import_lerobot(folder, out, say=typer.echo, **foreign)
        typer.echo(f"{out}: {sum(n for _, n in written)} frames imported into {len(written)} run file(s)")
        return
    if fmt != "folder":
        raise typer.BadParameter(f"expected folder or lerobot, got {fmt!r}", param_hint="'--format'")
    from dataset.import_images import Squaring
    from dataset.interchange import import_run

    if crop and pad:
        raise typer.BadParameter("give --crop or --pad, not both", param_hint="'--crop' / '--pad'")
    record = ""
    if profile is not None:
        from sensor_sim.profile import load_profile

        record = load_profile(profile).record()
    frames = import_run(
        folder,
        out,
        mm_per_px=mm_per_px,
        object_name=object_name,
        sensor=sensor,
        sensor_profile=record,
        squaring=Squaring("crop" if crop else "pad" if pad else None, size),
        ignore_columns=tuple(c.strip() for c in (ignore_columns or "").split(",") if c.strip()),
        say=typer.echo,
    )
    typer.echo(f"{out}: {frames} frames imported")
