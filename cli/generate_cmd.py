"""``generate``: a tactile frame for an object, a wrench and a pose, or every frame of a split's part.

The options are parsed and checked here; model/generation/generate_job.py loads the model and makes the frames.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from cli.model_options import SamplingPrecision, Threads, one_line_errors

generate_app = typer.Typer(add_completion=False)


def _numbers(text: str, n: int, what: str, limits: list[tuple[float, str]]) -> list[float]:
    """``n`` finite comma-separated numbers, each within ±its limit (``limits``: (bound, unit) per value)."""
    import math

    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise typer.BadParameter(f"{what}: expected {n} comma-separated numbers, got {text!r}") from None
    if len(values) != n:
        raise typer.BadParameter(f"{what}: expected {n} comma-separated numbers, got {len(values)} in {text!r}")
    for k, (v, (bound, unit)) in enumerate(zip(values, limits)):
        if not math.isfinite(v) or abs(v) > bound:
            raise typer.BadParameter(
                f"{what}: value {k + 1} is {v:g}; expected a finite number within ±{bound:g} {unit}"
            )
    return values


@generate_app.command()
@one_line_errors
def generate(
    checkpoint: Annotated[
        Path, typer.Option(help="A run directory written by `train --out DIR`: DIR, or DIR/checkpoint as train prints.")
    ],
    out: Annotated[Path, typer.Option(help="The generated frame (PNG); with --split, a folder of PNGs.")],
    object_image: Annotated[
        Optional[str],
        typer.Option(
            "--object",
            help=(
                "The object: a PNG/JPEG of its contact face spanning the sensor's field of view, a library object name "
                "(e.g. sphere10mm) or a run file (.h5, its object image); needed unless --split (default: none)."
            ),
        ),
    ] = None,
    wrench: Annotated[
        Optional[str], typer.Option(help="Fx,Fy,Fz (N),Mx,My,Mz (N·mm); needed unless --split (default: none).")
    ] = None,
    pose: Annotated[
        str,
        typer.Option(
            help="x,y (mm),theta (deg) of the object on the sensor, or x,y,z (mm),theta with z the depth from the "
            "contact point (negative into the gel). A physics-conditioned model given x,y,theta renders at the depth "
            "where the simulator's contact gives the wrench's Fz, and says which."
        ),
    ] = "0,0,0",
    split: Annotated[
        Optional[Path],
        typer.Option(
            help="Instead of --object/--wrench: generate every frame of a split's part (conditions from its runs). "
            "Default: none."
        ),
    ] = None,
    part: Annotated[str, typer.Option(help="With --split: the part to generate (train, val or test).")] = "test",
    limit: Annotated[
        Optional[int], typer.Option(help="With --split: at most this many frames, spread evenly (default: all).", min=1)
    ] = None,
    steps: Annotated[int, typer.Option(help="Sampler steps.", min=1, max=1000)] = 50,
    sampler: Annotated[str, typer.Option(help="ddim, ddpm or dpm.")] = "ddim",
    guidance: Annotated[float, typer.Option(help="Classifier-free guidance weight (1: none).", min=0.0)] = 1.0,
    seed: Annotated[int, typer.Option(help="Noise seed: the same seed gives the same frames.")] = 0,
    size: Annotated[
        Optional[int],
        typer.Option(
            help="Write the frame at this many pixels square (default: the model's own size; larger is upsampled, and "
            "says so).",
            min=8,
            max=4096,
        ),
    ] = None,
    device: Annotated[Optional[str], typer.Option(help="cpu or cuda (default: cuda when available).")] = None,
    threads: Threads = None,
    mixed_precision: SamplingPrecision = "auto",
):
    """Generate a tactile frame for an object, a wrench and a pose, or every frame of a split."""
    from dataset.import_checks import FORCE_N, POSE_LIMIT, TORQUE_NMM
    from model.denoiser.threads import set_threads
    from model.generation.generate_job import GenerateOptions
    from model.generation.generate_job import generate as generate_frames

    set_threads(threads)  # the output stays the frame's line (or one error line)
    w: list[float] | None = None
    p: list[float] | None = None
    if split is None:  # the options checked before the model loads
        if object_image is None or wrench is None:
            raise typer.BadParameter("give --object and --wrench, or --split")
        w = _numbers(wrench, 6, "--wrench", [(FORCE_N, "N")] * 3 + [(TORQUE_NMM, "N·mm")] * 3)
        four = pose.count(",") == 3
        p = _numbers(
            pose, 4 if four else 3, "--pose", [(POSE_LIMIT, "mm")] * (3 if four else 2) + [(POSE_LIMIT, "deg")]
        )
    options = GenerateOptions(
        checkpoint,
        out,
        object_source=object_image,
        wrench=None if w is None else tuple(w),
        pose=None if p is None else tuple(p),
        split=split,
        part=part,
        limit=limit,
        steps=steps,
        sampler=sampler,
        guidance=guidance,
        seed=seed,
        size=size,
        device=device,
        precision=mixed_precision,
    )
    made = generate_frames(options, log=typer.echo)
    if made.frames is not None:
        typer.echo(f"{out}: {made.frames} frames (PNG, named RUN-FRAME.png) and index.csv")
        return
    assert w is not None and p is not None  # checked above
    native = made.native
    note = f"the model's own size, {native}x{native}"
    if size is not None and size != native:
        note = f"{'upsampled' if size > native else 'downsampled'} from the model's {native}x{native}"
    if made.physics_z is not None:
        note += f"; physics render at z {made.physics_z:+.3f} mm, where the contact gives Fz {w[2]:g} N"
        if len(p) == 4:
            note += " (this model renders at the depth Fz implies: the z given is not used)"
    typer.echo(f"{out}: {made.width}x{made.height} ({note})")
