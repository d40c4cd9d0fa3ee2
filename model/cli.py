"""``train``: the contact-condition-guided diffusion model on a dataset split.

Not yet: validation sample PNGs, several GPUs through accelerate, `generate` and
`evaluate` (the model issue is open).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

app = typer.Typer(add_completion=False)


@app.command()
def train(
    data: Annotated[Path, typer.Option(help="A split directory from `dataset split` (split.json + index files).")],
    out: Annotated[Path, typer.Option(help="Run directory: checkpoint/ (safetensors) is written here.")],
    preset: Annotated[str, typer.Option(help="Model size: tiny (CPU, 32 px) or paper (GPU, 256 px).")] = "tiny",
    steps: Annotated[int, typer.Option(help="Optimisation steps in all.", min=1)] = 2000,
    batch_size: Annotated[int, typer.Option(help="Images per step.", min=1)] = 16,
    lr: Annotated[float, typer.Option(help="Adam learning rate.", min=0.0)] = 2e-4,
    checkpoint_every: Annotated[int, typer.Option(help="Steps between checkpoints.", min=1)] = 500,
    seed: Annotated[int, typer.Option(help="Seed of the weights, the data order and the noise.")] = 0,
    resume: Annotated[bool, typer.Option(help="Continue from OUT/checkpoint exactly where it stopped.")] = False,
    device: Annotated[Optional[str], typer.Option(help="cpu or cuda (default: cuda when available).")] = None,
):
    """Train the denoiser; progress shows the loss and images/s; checkpoints are safetensors."""
    import torch

    from dataset.split import SplitError
    from model.config import preset as make_preset
    from model.trainer import CheckpointError, TrainConfig, Trainer

    try:
        model_cfg = make_preset(preset)
        cfg = TrainConfig(steps=steps, batch_size=batch_size, lr=lr, checkpoint_every=checkpoint_every, seed=seed)
        trainer = Trainer(model_cfg, cfg, data, out, device=device or ("cuda" if torch.cuda.is_available() else "cpu"),
                          log=typer.echo)
        if resume:
            trainer.resume()
            typer.echo(f"resumed at step {trainer.step}")
        trainer.train()
        typer.echo(f"checkpoint: {trainer.save()}")
    except (KeyError, ValueError, SplitError, CheckpointError, FileNotFoundError) as exc:
        typer.secho(f"error: {exc}", fg=typer.colors.RED, err=True)
        raise typer.Exit(1)


generate_app = typer.Typer(add_completion=False)


def _numbers(text: str, n: int, what: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise typer.BadParameter(f"{what}: expected {n} comma-separated numbers, got {text!r}") from None
    if len(values) != n:
        raise typer.BadParameter(f"{what}: expected {n} comma-separated numbers, got {len(values)} in {text!r}")
    return values


@generate_app.command()
def generate(
    checkpoint: Annotated[Path, typer.Option(help="A run directory written by `train`.")],
    object_image: Annotated[Path, typer.Option("--object", help="The object's contact face (PNG/JPEG).")],
    wrench: Annotated[str, typer.Option(help="Fx,Fy,Fz (N),Mx,My,Mz (N·mm).")],
    out: Annotated[Path, typer.Option(help="The generated tactile frame (PNG).")],
    pose: Annotated[str, typer.Option(help="x,y (mm),theta (deg) of the object on the sensor.")] = "0,0,0",
    steps: Annotated[int, typer.Option(help="Sampler steps.", min=1, max=1000)] = 50,
    sampler: Annotated[str, typer.Option(help="ddim, ddpm or dpm.")] = "ddim",
    seed: Annotated[int, typer.Option(help="Noise seed: the same seed gives the same frame.")] = 0,
):
    """Generate a tactile frame for an object image, a wrench and a pose."""
    import cv2

    from model.inference import TrainedModel
    from model.trainer import CheckpointError

    w = _numbers(wrench, 6, "--wrench")
    p = _numbers(pose, 3, "--pose")
    img = cv2.imread(str(object_image), cv2.IMREAD_COLOR)
    if img is None:
        typer.secho(f"error: {object_image}: cannot read the object image", fg=typer.colors.RED, err=True)
        raise typer.Exit(1)
    try:
        frame = TrainedModel.load(checkpoint).generate(img, w, p, steps=steps, sampler=sampler, seed=seed)
    except (CheckpointError, ValueError) as exc:
        typer.secho(f"error: {exc}", fg=typer.colors.RED, err=True)
        raise typer.Exit(1)
    cv2.imwrite(str(out), frame)
    typer.echo(f"{out}: {frame.shape[1]}x{frame.shape[0]}")


evaluate_app = typer.Typer(add_completion=False)


@evaluate_app.command()
def evaluate(
    checkpoint: Annotated[Path, typer.Option(help="A run directory written by `train`.")],
    split: Annotated[Path, typer.Option(help="The split directory; its test part is evaluated.")],
    out: Annotated[Path, typer.Option(help="Folder for report.md and metrics.json.")],
    settings: Annotated[str, typer.Option(help="Sampler settings as sampler:steps, comma-separated.")] = "ddim:50",
    limit: Annotated[Optional[int], typer.Option(help="Evaluate at most this many test frames.", min=1)] = None,
    markers: Annotated[bool, typer.Option(help="Also the marker displacement error (marker sensors).")] = False,
    seed: Annotated[int, typer.Option(help="Noise seed.")] = 0,
):
    """MSE, MAE, SSIM, PSNR (and marker error) per sampler setting, against seconds per image."""
    from model.evaluate import evaluate as run, report
    from model.trainer import CheckpointError

    try:
        pairs = [(s.split(":")[0], int(s.split(":")[1])) for s in settings.split(",")]
    except (IndexError, ValueError):
        raise typer.BadParameter(f"--settings: expected sampler:steps[,sampler:steps...], got {settings!r}") from None
    try:
        rows = run(checkpoint, split, settings=pairs, limit=limit, markers=markers, seed=seed)
    except (CheckpointError, ValueError, KeyError) as exc:
        typer.secho(f"error: {exc}", fg=typer.colors.RED, err=True)
        raise typer.Exit(1)
    for r in rows:
        typer.echo(f"{r.setting}: MSE {r.mse:.2f}  MAE {r.mae:.2f}  SSIM {r.ssim:.3f}  PSNR {r.psnr:.2f}  "
                   f"{r.seconds_per_image:.3f} s/image")
    typer.echo(f"report: {report(rows, out, title=f'Evaluation of {checkpoint} on {split}')}")


def main() -> None:
    app()


def generate_main() -> None:
    generate_app()


def evaluate_main() -> None:
    evaluate_app()
