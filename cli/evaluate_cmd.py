"""``evaluate``: a trained run's metrics on a split's test parts against run time, and its report.

The options are parsed and checked here; model/evaluation/evaluate_job.py evaluates and writes the report.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from cli.model_options import SamplingPrecision, Threads, one_line_errors, sampler_settings

evaluate_app = typer.Typer(add_completion=False)


@evaluate_app.command()
@one_line_errors
def evaluate(
    checkpoint: Annotated[
        Path, typer.Option(help="A run directory written by `train --out DIR`: DIR, or DIR/checkpoint as train prints.")
    ],
    split: Annotated[
        Path,
        typer.Option(help="The split directory; its test parts are evaluated (test, and test_object if it has one)."),
    ],
    out: Annotated[Path, typer.Option(help="Folder for report.md, metrics.json and the figures (PNG).")],
    settings: Annotated[
        str,
        typer.Option(
            help="Sampler settings as sampler:steps, comma-separated (ddim, ddpm, dpm); each is a row and a "
            "point on the error-against-run-time plot."
        ),
    ] = "ddim:10,ddim:25,ddim:50",
    part: Annotated[
        Optional[str],
        typer.Option(
            help="The split part to evaluate (default: every test part the split has: test, and test_object, "
            "the objects held out of training by `dataset split --hold-out`), each a section of one report."
        ),
    ] = None,
    limit: Annotated[
        Optional[int],
        typer.Option(help="At most this many frames of each part, spread evenly over it (default: all).", min=1),
    ] = None,
    force_sweep: Annotated[
        bool,
        typer.Option(
            help="The force-response check: at a few test poses, sweep Fz, Fx, Fy and Mz over their training "
            "range and measure the generated contact's area, centroid and shading against real frames at "
            "matching force (or the physics render); generated with the first --settings entry."
        ),
    ] = True,
    sweep_poses: Annotated[
        int,
        typer.Option(help="Poses of each part the force sweep is made at, spread over the field and the loads.", min=1),
    ] = 8,
    sweep_points: Annotated[int, typer.Option(help="Values of each wrench component per sweep.", min=2)] = 7,
    sweep_beyond: Annotated[
        float,
        typer.Option(
            help="Fz is also swept at two values up to this share of its training range past the training maximum "
            "(how the model degrades where it was never trained; 0: not).",
            min=0.0,
            max=10.0,
        ),
    ] = 1.0,
    markers: Annotated[
        Optional[bool],
        typer.Option(
            "--markers/--no-markers", help="Marker displacement error (default: when the sensor has markers)."
        ),
    ] = None,
    baseline: Annotated[
        bool, typer.Option(help="The physics-render row: the simulator's render of each frame at its measured pose.")
    ] = True,
    batch_size: Annotated[int, typer.Option(help="Frames generated at once (memory).", min=1)] = 64,
    seed: Annotated[int, typer.Option(help="Noise seed.")] = 0,
    device: Annotated[Optional[str], typer.Option(help="cpu or cuda (default: cuda when available).")] = None,
    profile: Annotated[
        Optional[Path],
        typer.Option(
            help="Sensor profile TOML for the physics-render row (`rig sensor calibrate` writes one). Default: the "
            "profile each run file records (found again by its content hash); a run that records none is refused "
            "(give this, or --no-baseline): its sensor is never guessed.",
            dir_okay=False,
        ),
    ] = None,
    threads: Threads = None,
    mixed_precision: SamplingPrecision = "auto",
):
    """MSE, MAE, SSIM, PSNR (and marker error) per sampler setting against seconds per image, beside the
    physics render and the paper's table."""
    from model.denoiser.threads import set_threads
    from model.evaluation.evaluate_job import EvaluateOptions
    from model.evaluation.evaluate_job import evaluate as evaluate_checkpoint

    set_threads(threads)  # the report's context states the count
    pairs = sampler_settings(settings)
    if any(steps < 1 for _, steps in pairs):
        raise typer.BadParameter(f"--settings {settings!r}: every step count must be at least 1")
    options = EvaluateOptions(
        checkpoint,
        split,
        out,
        tuple(pairs),
        part=part,
        limit=limit,
        force_sweep=force_sweep,
        sweep_poses=sweep_poses,
        sweep_points=sweep_points,
        sweep_beyond=sweep_beyond,
        markers=markers,
        baseline=baseline,
        batch_size=batch_size,
        seed=seed,
        device=device,
        profile=profile,
        precision=mixed_precision,
    )
    evaluated = evaluate_checkpoint(options, log=typer.echo)
    for ev in evaluated.parts:
        for r in ev.rows + ([ev.baseline] if ev.baseline else []):
            mk = "" if r.marker_px is None else f"  markers {r.marker_px:.2f} px"
            typer.echo(
                f"{ev.part:>11} {r.setting:>16}: MSE {r.mse:7.2f}  MAE {r.mae:5.2f}  SSIM {r.ssim:.3f}  "
                f"PSNR {r.psnr:5.2f}{mk}  {r.seconds_per_image:.4f} s/image"
            )
    typer.echo(f"report: {evaluated.write_report()}")
