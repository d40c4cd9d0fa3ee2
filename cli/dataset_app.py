"""``dataset``: turn collected runs into training data. Commands parse, then call the library.

torch is not imported here: only the training Dataset (dataset.torch_dataset) needs it.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Annotated, Optional

import typer

from cli import dataset_exchange as exchange
from cli.options import number

app = typer.Typer(
    help="Run files (HDF5) → validated, split training data with contact conditions.",
    no_args_is_help=True,
    add_completion=False,
)

OFFSET_WARN = 0.1  # of the frame's width: a condition farther from the contact than this is a wrong pose or scale

Paths = Annotated[list[Path], typer.Argument(help="Run files (HDF5) written by `rig run-protocol`.")]


def friendly(fn):
    """Every failure is one red line and exit 1, never a traceback: the expected ones in their own
    words, anything else naming its type (cli/one_line.py)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from cli.one_line import passes_through, unexpected
        from common.errors import ToolError

        try:
            return fn(*args, **kwargs)
        except (ToolError, FileNotFoundError, ValueError, KeyError) as exc:
            message = f"{exc}"
        except OSError as exc:  # a read-only or full disk, a folder we may not write: named, never a traceback
            where = f"{exc.filename}: " if exc.filename else ""
            message = f"{where}{exc.strerror or exc}"
        except Exception as exc:
            if passes_through(exc):
                raise
            message = unexpected(exc, "dataset")
        except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM/SIGHUP while a file is written (whole_run)
            name = getattr(exc, "signal_name", "SIGINT")
            typer.secho(f"interrupted ({name}): what was being written was removed", fg=typer.colors.YELLOW, err=True)
            raise typer.Exit(getattr(exc, "exit_code", 130)) from None
        typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
        raise typer.Exit(1)

    return wrapper


@app.command()
@friendly
def info(paths: Paths):
    """Frames, object, sensor kind, wrench ranges, status and duration of each run (also while it grows)."""
    from common.wording import status_text
    from dataset.pose_convention import DESCRIPTION as POSE_DESCRIPTION
    from dataset.runs import summarize
    from rig.types import WRENCH_COMPONENTS, WRENCH_UNITS

    for path in paths:
        s = summarize(path)
        typer.echo(
            f"{s.path}: {s.frames}/{s.frames_planned} frames {s.frame_shape[1]}x{s.frame_shape[0]}, "
            f"{status_text(s.status, s.reason)}; protocol {s.protocol}, object {s.object_name}, "
            f"sensor {s.sensor_kind}, {s.duration_s:.0f} s, {s.mm_per_px:.4f} mm/px"
        )
        typer.echo(f"  pose: {POSE_DESCRIPTION}")
        typer.echo(f"  sensor profile: {s.profile_line}")
        if s.imported:
            typer.echo(f"  imported from {s.imported}")
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
    from common.eta import Eta
    from dataset.runs import check_run

    bad = 0
    sizes = [Path(p).stat().st_size if Path(p).is_file() else 0 for p in paths]  # reading time goes with bytes
    eta = Eta(sum(sizes) or 1)
    for i, path in enumerate(paths):
        result = check_run(path, max_skew_s=max_skew_s, sample_frames=sample)
        progress = f"  ({i + 1}/{len(paths)} files, {eta.line(sum(sizes[: i + 1]) or 1)})"
        typer.echo(f"{path}: {'ok' if not result.findings else f'{len(result.findings)} finding(s)'}{progress}")
        for item in result.findings:
            typer.echo(f"  {path}: {item}")
        for item in result.notes:
            typer.echo(f"  {path}: note: {item}")
        bad += bool(result.findings)
    if bad:
        raise typer.Exit(1)


def _listed(text: str | None, option: str) -> list[str]:
    if text is None:
        return []
    names = [name.strip() for name in text.split(",") if name.strip()]
    if not names:
        raise typer.BadParameter(f"{option} {text!r}: expected run files joined by ','")
    return names


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
    hold_out: Annotated[
        Optional[str],
        typer.Option(
            help="Objects never seen in training, comma-separated (heart,ring): all their frames form the part "
            "test_object; the other objects are split by RATIO and --by frame or run as usual. Default: none."
        ),
    ] = None,
    hold_out_top: Annotated[
        Optional[str],
        typer.Option(
            help="COMPONENT:N such as Fz:5: the N frames with the largest signed value of that wrench component "
            "(Fx, Fy, Fz in N; Mx, My, Mz in N·mm; a press reads positive Fz, so Fz:N is the N hardest presses) "
            "form the part test_force, never trained on; the rest is split by RATIO. Default: none."
        ),
    ] = None,
    test_runs: Annotated[
        Optional[str],
        typer.Option(
            help="Runs (of PATHS, comma-separated) whose frames are the test part; the other runs are split by "
            "RATIO's other parts (train, or train:val). Default: the test part is drawn by RATIO."
        ),
    ] = None,
    hold_out_runs: Annotated[
        Optional[str],
        typer.Option(
            help="Runs (of PATHS, comma-separated) never trained on: their frames form the part test_run. "
            "Default: none."
        ),
    ] = None,
):
    """Split runs deterministically; wrench statistics come from the training part only. Every run file is
    verified whole first (schema, rows, every frame's checksum) and its identity recorded, so that train and
    evaluate refuse a file changed since."""
    from dataset.split import make_split

    held = [name for name in (hold_out or "").split(",") if name.strip()]
    if hold_out is not None and not held:
        raise typer.BadParameter(f"--hold-out {hold_out!r}: expected object names joined by ',' such as heart,ring")
    result = make_split(
        paths,
        ratio,
        out,
        seed=seed,
        by=by,
        allow_incomplete=allow_incomplete,
        hold_out=held,
        hold_out_top=hold_out_top,
        test_runs=_listed(test_runs, "--test-runs"),
        hold_out_runs=_listed(hold_out_runs, "--hold-out-runs"),
        warn=lambda m: typer.secho(m, fg=typer.colors.YELLOW, err=True),
    )
    sizes = ", ".join(f"{k} {len(v)}" for k, v in result.parts.items())
    typer.echo(f"{out}: {sizes} frames from {len(result.runs)} run(s) (by {by}, seed {seed})")
    for run, where in zip(result.runs, result.where or []):  # which run went where, as split.json records it
        typer.echo(f"  {run}: " + ", ".join(f"{part} {frames}" for part, frames in where.items()))
    if held:
        typer.echo(f"  held out (test_object): {', '.join(sorted(set(held)))}")
    top = result.held_out_top
    if top:
        typer.echo(
            f"  held out (test_force): the {top['frames']} frame(s) of largest {top['component']}, "
            f"{top['smallest_held_out']:g}–{top['largest_held_out']:g} {top['unit']} "
            f"(largest kept {top['largest_kept']:g} {top['unit']})"
        )


@app.command()
@friendly
def merge(paths: Paths, out: Annotated[Path, typer.Option(help="The merged run file to write; must not exist.")]):
    """Merge runs of one object, sensor, profile, scale and frame size into one file that validates: every
    source verified first, time offset per source so it keeps increasing (docs/dataset.md)."""
    from dataset.merge import merge_runs

    typer.echo(f"{out}: {merge_runs(paths, out)} frames from {len(paths)} run(s)")


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


@app.command()
@friendly
def preview(
    path: Annotated[Path, typer.Argument(help="A run file.")],
    out: Annotated[Path, typer.Option(help="The contact sheet PNG to write.")],
    tiles: Annotated[int, typer.Option(help="How many evenly spaced frames.", min=1, max=200)] = 24,
    condition: Annotated[
        bool,
        typer.Option(
            "--condition", help="Overlay the condition (object at the pose) and mark it beside the contact seen."
        ),
    ] = False,
):
    """A contact sheet PNG of frames labelled with their wrenches and poses; --condition overlays the
    model's condition on each, so a mirrored or shifted pose shows at a glance."""
    from dataset.preview import contact_sheet

    sheet = contact_sheet(path, out, tiles=tiles, condition=condition)
    typer.echo(f"{out}: {len(sheet.tiles)} frames")
    if condition:
        median = sheet.median_offset_px
        if median is None:
            typer.echo("  no frame shows both a contact and the object in view: no offset measured")
            return
        typer.echo(
            f"  condition to contact: median {median:.1f} px of {sheet.frame_px} "
            f"over {len(sheet.offsets_px)} frame(s) with a contact"
        )
        if median > OFFSET_WARN * sheet.frame_px:
            typer.secho(
                f"  warning: the condition lies {median:.0f} px from the contact seen in the frames: check the "
                "pose convention (+y up, docs/dataset.md), mm_per_px and the contact origin",
                fg=typer.colors.YELLOW,
                err=True,
            )


@app.command()
@friendly
def view(
    path: Annotated[Path, typer.Argument(help="A run file (HDF5), also one still being written.", dir_okay=False)],
    host: Annotated[
        str,
        typer.Option(help="Address to listen on; any other than 127.0.0.1 needs the access token printed at start."),
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port (0: any free port).", min=0, max=65535)] = 8766,
):
    """Open a run file in the console's run browser (frames, wrench, pose and phases over time)."""
    from acquisition.run_reader import RunReader
    from cli.console.launch import run_console

    RunReader.open(path).close()  # verified first: a damaged or malformed file is one line, not a page of errors
    run_console(
        config=None, sim=False, live=False, host=host, port=port, runs=[path.parent], files=[path], say=typer.echo
    )


app.command()(friendly(exchange.export))
app.command("import")(friendly(exchange.import_))


def main() -> None:
    app()
