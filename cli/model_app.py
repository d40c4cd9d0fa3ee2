"""``train``, ``generate``, ``evaluate`` and ``compare``: the contact-condition-guided diffusion model.

``train`` is here; the others' options are in cli/generate_cmd.py, cli/evaluate_cmd.py and
cli/compare_cmd.py, and each command's work in model/ (``training/train_job.py``, ``generation/generate_job.py``,
``evaluation/evaluate_job.py``, ``compare/compare_job.py``). The console scripts' entry points are here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from cli.compare_cmd import compare, compare_app
from cli.evaluate_cmd import evaluate, evaluate_app
from cli.generate_cmd import generate, generate_app
from cli.model_options import Threads, one_line_errors

__all__ = ["app", "compare", "compare_app", "evaluate", "evaluate_app", "generate", "generate_app", "main", "train"]

app = typer.Typer(add_completion=False)


@app.command()
@one_line_errors
def train(
    data: Annotated[Path, typer.Option(help="A split directory from `dataset split` (split.json + index files).")],
    out: Annotated[
        Path,
        typer.Option(help="Run directory: checkpoint/ (safetensors) and samples/ (validation PNGs) are written here."),
    ],
    config: Annotated[
        Optional[Path],
        typer.Option(
            help="A model TOML: preset, \\[model] and \\[train] tables (docs/model.md). Options given here win. "
            "Default: none (the preset)."
        ),
    ] = None,
    preset: Annotated[
        Optional[str],
        typer.Option(help="Model size: tiny (CPU, 32 px) or paper (GPU, 256 px). Default: the config's, else tiny."),
    ] = None,
    image_size: Annotated[Optional[int], typer.Option(help="Image side in px (default: the preset's).", min=8)] = None,
    conditioning: Annotated[
        Optional[str],
        typer.Option(
            help="Condition components joined by +: plane (the paper's H(F)), embedding (a learned wrench "
            "embedding), physics (the simulator's render at each frame's measured pose; library objects only), e.g. "
            "plane+embedding or physics+plane+embedding. Default: the config's, else the measured best for the "
            "split's sensor kind (docs/model.md)."
        ),
    ] = None,
    prediction: Annotated[
        Optional[str],
        typer.Option(
            help="Network target: sample (y0), epsilon (the paper's) or v_prediction (default: the preset's, sample)."
        ),
    ] = None,
    target: Annotated[
        Optional[str],
        typer.Option(
            help="What is denoised: frame (the paper's) or physics_residual (the frame minus the physics render; "
            "needs physics conditioning). Default: the config's, else frame."
        ),
    ] = None,
    physics_depth: Annotated[
        Optional[str],
        typer.Option(
            help="Where physics conditioning renders each frame: pose (at its measured z) or force (at the depth "
            "where the simulator's contact gives its measured Fz, so the force shapes the picture; docs/model.md). "
            "Default: the config's, else pose."
        ),
    ] = None,
    residual_gain: Annotated[
        Optional[float],
        typer.Option(
            help="With target physics_residual: multiply the residual by this before it is noised (a real sensor's "
            "residual is a few grey levels, which the noise drowns at gain 1; docs/model.md). Default: the config's, "
            "else 1.",
            min=0.0,
        ),
    ] = None,
    force_augment: Annotated[
        Optional[float],
        typer.Option(
            help="With physics depth force: also train on each frame at Fz x (1 +- S, 1 +- S/2), its render at that "
            "load and its contact grown or shrunk as the render's (an assumption; docs/model.md). 0: off (default).",
            min=0.0,
        ),
    ] = None,
    steps: Annotated[Optional[int], typer.Option(help="Optimisation steps in all (default 2000).", min=1)] = None,
    batch_size: Annotated[
        Optional[int], typer.Option(help="Images per step, over all GPUs (default 16).", min=1)
    ] = None,
    lr: Annotated[
        Optional[float],
        typer.Option(help="Adam learning rate (default: the preset's, 1e-3 tiny, 2e-4 paper).", min=0.0),
    ] = None,
    checkpoint_every: Annotated[
        Optional[int], typer.Option(help="Steps between checkpoints (default 500).", min=1)
    ] = None,
    sample_every: Annotated[
        Optional[int], typer.Option(help="Steps between validation sample PNGs; 0: never (default 500).", min=0)
    ] = None,
    seed: Annotated[
        Optional[int], typer.Option(help="Seed of the weights, the data order and the noise (default 0).")
    ] = None,
    mixed_precision: Annotated[
        Optional[str],
        typer.Option(
            help="auto (CUDA: bf16 where supported, else fp16; CPU: bf16 where the CPU has it natively, else "
            "none), no, fp16 or bf16 (default auto)."
        ),
    ] = None,
    resume: Annotated[bool, typer.Option(help="Continue from OUT/checkpoint exactly where it stopped.")] = False,
    device: Annotated[
        Optional[str],
        typer.Option(help="cpu or cuda (default: cuda when available; under `accelerate launch`, each process's GPU)."),
    ] = None,
    profile: Annotated[
        Optional[Path],
        typer.Option(
            help="Sensor profile TOML of the physics conditioning (`rig sensor calibrate` writes one), for every run. "
            "Default: the profile each run records; a run that records none is refused for physics conditioning "
            "(never rendered through another sensor's profile).",
            dir_okay=False,
        ),
    ] = None,
    override_profile: Annotated[
        bool,
        typer.Option(
            "--override-profile",
            help="Render runs that record another sensor profile than --profile through --profile anyway. Default: "
            "such a run is refused, naming both profiles.",
        ),
    ] = False,
    threads: Threads = None,
):
    """Train the denoiser; progress shows the loss and images/s; checkpoints are safetensors.

    Several GPUs: `accelerate launch -m cli.model_app --data ... --out ...` runs this same command.
    """
    from model.training.train_job import TrainOptions, end_process
    from model.training.train_job import train as run_training

    options = TrainOptions(
        data,
        out,
        config=config,
        preset=preset,
        image_size=image_size,
        conditioning=conditioning,
        prediction=prediction,
        target=target,
        physics_depth=physics_depth,
        residual_gain=residual_gain,
        force_augment=force_augment,
        steps=steps,
        batch_size=batch_size,
        lr=lr,
        checkpoint_every=checkpoint_every,
        sample_every=sample_every,
        seed=seed,
        mixed_precision=mixed_precision,
        resume=resume,
        device=device,
        profile=profile,
        override_profile=override_profile,
        threads=threads,
    )
    trained = run_training(options, log=typer.echo)
    if trained.is_main:
        typer.echo(f"checkpoint: {trained.checkpoint}")
    end_process(trained)


def main() -> None:
    app()


def generate_main() -> None:
    generate_app()


def evaluate_main() -> None:
    evaluate_app()


def compare_main() -> None:
    compare_app()


if __name__ == "__main__":  # `accelerate launch -m cli.model_app ...`
    main()
