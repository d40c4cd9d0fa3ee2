"""The ``evaluate`` command's work: a checkpoint evaluated on a split's test parts, then its report.

``evaluate(options, log)`` evaluates every part asked for (model/evaluation/evaluate.py's ``evaluate_parts``)
with each sampler setting, the physics-render row and the force sweep, and hands back the
evaluated parts (their rows, for the command to print) with the report's title;
``Evaluated.write_report()`` then writes the report (report.md, metrics.json, the figures).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable


@dataclass(frozen=True)
class EvaluateOptions:
    """``evaluate``'s options as parsed: ``settings`` the (sampler, steps) pairs, checked."""

    checkpoint: Path
    split: Path
    out: Path
    settings: tuple[tuple[str, int], ...]
    part: str | None = None
    limit: int | None = None
    force_sweep: bool = True
    sweep_poses: int = 8
    sweep_points: int = 7
    sweep_beyond: float = 1.0
    markers: bool | None = None
    baseline: bool = True
    batch_size: int = 64
    seed: int = 0
    device: str | None = None
    profile: Path | None = None
    precision: str = "auto"  # the network's arithmetic when sampling (model/denoiser/precision.py)


@dataclass(frozen=True)
class Evaluated:
    """The evaluated parts (model/evaluation/eval_results.py's ``Evaluation``, in order) and the report to write."""

    parts: list
    out: Path
    title: str

    def write_report(self) -> Path:
        """Write the one report of every part into ``out``; its path."""
        from model.evaluation.evaluate import report

        return report(self.parts, self.out, title=self.title)


def evaluate(opts: EvaluateOptions, log: Callable[[str], None]) -> Evaluated:
    """Evaluate the checkpoint on the split's parts; ``log`` says each part and step as it comes."""
    import torch

    from model.denoiser.checkpoint import run_folder
    from model.evaluation.evaluate import SweepOptions, evaluate_parts

    pairs = list(opts.settings)
    sweep = (
        SweepOptions(opts.sweep_poses, opts.sweep_points, pairs[0][0], pairs[0][1], beyond=opts.sweep_beyond)
        if opts.force_sweep
        else None
    )
    evs = evaluate_parts(
        opts.checkpoint,
        opts.split,
        parts=[opts.part] if opts.part else None,
        settings=pairs,
        limit=opts.limit,
        markers=opts.markers,
        baseline=opts.baseline,
        seed=opts.seed,
        batch_size=opts.batch_size,
        device=opts.device or ("cuda" if torch.cuda.is_available() else "cpu"),
        precision=opts.precision,
        log=log,
        profile=opts.profile,
        sweep=sweep,
    )
    parts = ", ".join(ev.part for ev in evs)
    title = (  # names, not paths
        f"Evaluation of {run_folder(opts.checkpoint).resolve().name} on {opts.split.resolve().name} ({parts})"
    )
    return Evaluated(evs, opts.out, title)
