"""``compare``: candidate training settings over seeds on one split, each evaluated alike, in one report.

The options are parsed and checked here; model/compare/compare_job.py trains, evaluates and writes compare.md.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from cli.model_options import Threads, one_line_errors, sampler_settings

compare_app = typer.Typer(add_completion=False)


@compare_app.command()
@one_line_errors
def compare(
    data: Annotated[Path, typer.Option(help="A split directory from `dataset split`.")],
    out: Annotated[
        Path,
        typer.Option(help="Folder for compare.md, compare.json and each run (CANDIDATE/seed-S with its report)."),
    ],
    candidate: Annotated[
        list[str],
        typer.Option(
            help="A setting to compare, repeated: a conditioning, then key=value of model fields, e.g. plane, physics, "
            "physics,physics_depth=force,target=physics_residual."
        ),
    ],
    seeds: Annotated[str, typer.Option(help="Training seeds, comma-separated (at least 2 for a spread).")] = "0,1,2",
    config: Annotated[
        Optional[Path], typer.Option(help="A model TOML every candidate starts from (default: the preset).")
    ] = None,
    preset: Annotated[Optional[str], typer.Option(help="tiny or paper (default: the config's, else tiny).")] = None,
    image_size: Annotated[Optional[int], typer.Option(help="Image side in px (default: the preset's).", min=8)] = None,
    steps: Annotated[
        Optional[str],
        typer.Option(
            help="Training steps of every run (default 2000); several, comma-separated (400,1200): each candidate "
            "at each, a setting of its own named 'CANDIDATE @ N steps'."
        ),
    ] = None,
    batch_size: Annotated[Optional[int], typer.Option(help="Images per step (default 16).", min=1)] = None,
    lr: Annotated[Optional[float], typer.Option(help="Adam learning rate (default: the preset's).", min=0.0)] = None,
    settings: Annotated[
        str, typer.Option(help="Sampler settings of the evaluation, sampler:steps, comma-separated.")
    ] = "ddim:10",
    limit: Annotated[
        Optional[int], typer.Option(help="At most this many frames of each part (default: all).", min=1)
    ] = None,
    sweep_poses: Annotated[
        int,
        typer.Option(help="Poses of each part the force sweep is made at, spread over the field and the loads.", min=1),
    ] = 8,
    sweep_points: Annotated[int, typer.Option(help="Values of each wrench component per sweep.", min=2)] = 7,
    profile: Annotated[
        Optional[Path],
        typer.Option(
            help="Sensor profile TOML for runs that record none (physics conditioning and the physics row); "
            "default: each run's recorded one.",
            dir_okay=False,
        ),
    ] = None,
    report_only: Annotated[
        bool,
        typer.Option(
            "--report-only",
            help="Write compare.md again from the runs' saved evaluations (OUT/CANDIDATE/seed-S/report/"
            "metrics.json); nothing is trained or evaluated, and a missing run is named.",
        ),
    ] = False,
    threads: Threads = None,
):
    """Train every candidate setting with each seed on one split, evaluate each alike, and report per test part
    the mean ± spread over seeds beside the baselines; a setting leads only where the difference exceeds the
    spread."""
    from model.compare.compare import Candidate
    from model.compare.compare_job import CompareOptions
    from model.compare.compare_job import compare as run_comparison
    from model.denoiser.threads import set_threads

    threads_line = set_threads(threads)  # said once the comparison is set up
    cands = [Candidate.parse(c) for c in candidate]
    step_list = _step_counts(steps)
    if len(step_list) > 1:
        cands = [c.with_steps(n) for c in cands for n in step_list]
    try:
        seed_list = [int(s) for s in seeds.split(",") if s.strip()]
    except ValueError:
        raise typer.BadParameter(f"--seeds: expected whole numbers separated by commas, got {seeds!r}") from None
    options = CompareOptions(
        data,
        out,
        tuple(cands),
        tuple(seed_list),
        tuple(sampler_settings(settings)),
        step_counts=tuple(step_list),
        config=config,
        preset=preset,
        image_size=image_size,
        batch_size=batch_size,
        lr=lr,
        limit=limit,
        sweep_poses=sweep_poses,
        sweep_points=sweep_points,
        profile=profile,
        report_only=report_only,
        threads_line=threads_line,
    )
    typer.echo(f"comparison: {run_comparison(options, log=typer.echo)}")


def _step_counts(text: str | None) -> list[int]:
    """compare --steps: one or more whole numbers >= 1, comma-separated ([] when not given)."""
    if text is None:
        return []
    try:
        counts = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        counts = []
    if not counts or min(counts) < 1 or len(set(counts)) != len(counts):
        raise typer.BadParameter(f"--steps: expected different whole numbers >= 1, comma-separated, got {text!r}")
    return counts
