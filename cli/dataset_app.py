"""``dataset``: turn collected runs into training data. Commands parse, then call the library.

torch is not imported here: only the training Dataset (dataset.torch_dataset) needs it.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Annotated, Optional

import typer

from cli.options import number

app = typer.Typer(
    help="Run files (HDF5) → validated, split training data with contact conditions.",
    no_args_is_help=True,
    add_completion=False,
)

Paths = Annotated[list[Path], typer.Argument(help="Run files (HDF5) written by `rig run-protocol`.")]


def friendly(fn):
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from common.errors import ToolError

        try:
            return fn(*args, **kwargs)
        except (ToolError, FileNotFoundError, ValueError, KeyError) as exc:
            typer.secho(f"error: {exc}", fg=typer.colors.RED, err=True)
            raise typer.Exit(1) from None

    return wrapper


@app.command()
@friendly
def info(paths: Paths):
    """Frames, object, sensor kind, wrench ranges, status and duration of each run (also while it grows)."""
    from dataset.runs import summarize
    from rig.types import WRENCH_COMPONENTS, WRENCH_UNITS

    for path in paths:
        s = summarize(path)
        typer.echo(
            f"{s.path}: {s.frames}/{s.frames_planned} frames {s.frame_shape[1]}x{s.frame_shape[0]}, "
            f"{s.status}{' (' + s.reason + ')' if s.reason else ''}; protocol {s.protocol}, object {s.object_name}, "
            f"sensor {s.sensor_kind}, {s.duration_s:.0f} s, {s.mm_per_px:.4f} mm/px"
        )
        typer.echo(
            "  wrench: "
            + "  ".join(
                f"{c} [{lo:+.2f}, {hi:+.2f}] {u}"
                for c, lo, hi, u in zip(WRENCH_COMPONENTS, s.wrench_min, s.wrench_max, WRENCH_UNITS)
            )
        )


@app.command()
@friendly
def validate(
    paths: Paths,
    max_skew_s: Annotated[
        float, typer.Option(help="Largest acceptable wrench–frame skew, s.", callback=number(low=0.0, high=3600.0))
    ] = 0.1,
    sample: Annotated[
        Optional[int],
        typer.Option(help="Check only this many evenly spaced frames (faster); default: every frame.", min=1),
    ] = None,
):
    """Check every dataset and attribute of the schema, every checksum, every frame (black, constant, saturated),
    NaN/inf, time order, capture indices, status and reason, skew; one line per finding; exit 1 on findings."""
    from dataset.runs import check_run

    bad = 0
    for path in paths:
        result = check_run(path, max_skew_s=max_skew_s, sample_frames=sample)
        typer.echo(f"{path}: {'ok' if not result.findings else f'{len(result.findings)} finding(s)'}")
        for item in result.findings:
            typer.echo(f"  {path}: {item}")
        for item in result.notes:
            typer.echo(f"  {path}: note: {item}")
        bad += bool(result.findings)
    if bad:
        raise typer.Exit(1)


@app.command()
@friendly
def split(
    ratio: Annotated[str, typer.Argument(help="Parts as train:test (8:2) or train:val:test (7:1:2).")],
    paths: Paths,
    out: Annotated[Path, typer.Option(help="Directory for split.json and one NAME.npy index file per part.")],
    seed: Annotated[int, typer.Option(help="Random seed: the same seed gives the same split.", min=0)] = 0,
    by: Annotated[
        str, typer.Option(help="frame (the paper's way), run or object (a test object never seen in training).")
    ] = "frame",
    allow_incomplete: Annotated[
        bool, typer.Option(help="Use aborted or interrupted runs too (with a warning).")
    ] = False,
):
    """Split runs deterministically; wrench statistics come from the training part only."""
    from dataset.split import make_split

    result = make_split(
        paths,
        ratio,
        out,
        seed=seed,
        by=by,
        allow_incomplete=allow_incomplete,
        warn=lambda m: typer.secho(m, fg=typer.colors.YELLOW, err=True),
    )
    sizes = ", ".join(f"{k} {len(v)}" for k, v in result.parts.items())
    typer.echo(f"{out}: {sizes} frames from {len(result.runs)} run(s) (by {by}, seed {seed})")


@app.command()
@friendly
def merge(paths: Paths, out: Annotated[Path, typer.Option(help="The merged run file to write; must not exist.")]):
    """Merge runs of one object, sensor and frame size into one file (each frame keeps its source)."""
    from dataset.merge import merge_runs

    typer.echo(f"{out}: {merge_runs(paths, out)} frames from {len(paths)} run(s)")


@app.command()
@friendly
def export(
    path: Annotated[Path, typer.Argument(help="A run file.")],
    out: Annotated[Path, typer.Option(help="Folder for frames/*.png, frames.csv, object.png, run.json.")],
):
    """Export a run to PNG frames and a CSV of wrenches and poses (for people who don't use HDF5)."""
    from dataset.interchange import export_run

    typer.echo(f"{out}: {export_run(path, out)} frames")


@app.command()
@friendly
def compact(paths: Paths):
    """Rewrite old run files with compressed frames (lossless), verified frame by frame and row by row
    before the original is replaced; refuses a run that is being written."""
    from acquisition.run_compact import compact as compact_run

    for path in paths:
        done = compact_run(path)
        if done.done:
            typer.echo(
                f"{path}: {done.frames} frames compacted, {done.bytes_before / 1e6:,.1f} MB → "
                f"{done.bytes_after / 1e6:,.1f} MB ({done.bytes_after / max(done.bytes_before, 1):.2f})"
            )
        else:
            typer.echo(f"{path}: frames already compressed; unchanged")


def _mm_per_px(ctx: typer.Context, param: typer.CallbackParam, value: Optional[float]):
    """--mm-per-px: finite and in the import's calibration range, the option named (cli/options.py)."""
    from dataset.interchange import MM_PER_PX

    return number(low=MM_PER_PX[0], high=MM_PER_PX[1])(ctx, param, value)


@app.command("import")
@friendly
def import_(
    folder: Annotated[Path, typer.Argument(help="A folder in the export format (docs/dataset.md).")],
    out: Annotated[Path, typer.Option(help="The run file to write; must not exist.")],
    mm_per_px: Annotated[
        Optional[float],
        typer.Option(help="Frame calibration, mm per pixel (default: run.json's); 0.0001 to 10.", callback=_mm_per_px),
    ] = None,
    object_name: Annotated[Optional[str], typer.Option("--object", help="Object name (default: run.json's).")] = None,
):
    """Import tactile PNGs, a CSV of wrenches and poses and an object image from another rig."""
    from dataset.interchange import import_run

    typer.echo(f"{out}: {import_run(folder, out, mm_per_px=mm_per_px, object_name=object_name)} frames imported")


@app.command()
@friendly
def preview(
    path: Annotated[Path, typer.Argument(help="A run file.")],
    out: Annotated[Path, typer.Option(help="The contact sheet PNG to write.")],
    tiles: Annotated[int, typer.Option(help="How many evenly spaced frames.", min=1, max=200)] = 24,
):
    """A contact sheet PNG of frames labelled with their wrenches."""
    from dataset.preview import preview as sheet

    typer.echo(f"{out}: {sheet(path, out, tiles=tiles)} frames")


def main() -> None:
    app()
