"""The ``compare`` command's work: every candidate trained and evaluated per seed, then compare.md.

``compare(options, log)`` settles the base model config and the training fields every run shares
(the model TOML or the preset, with the options given), trains and evaluates each (candidate,
seed) through model/compare/compare.py, or gathers their saved evaluations (``report_only``), and writes
the comparison (model/compare/compare_report.py) with the context it was made in; its path comes back.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable


@dataclass(frozen=True)
class CompareOptions:
    """``compare``'s options as parsed: ``candidates`` (model/compare/compare.py's ``Candidate``, one per
    step count when several), ``seeds``, ``settings`` the (sampler, steps) pairs, ``step_counts``
    the --steps given ([] when not); ``threads_line``: what setting torch's threads said."""

    data: Path
    out: Path
    candidates: tuple
    seeds: tuple[int, ...]
    settings: tuple[tuple[str, int], ...]
    step_counts: tuple[int, ...] = ()
    config: Path | None = None
    preset: str | None = None
    image_size: int | None = None
    batch_size: int | None = None
    lr: float | None = None
    limit: int | None = None
    sweep_poses: int = 8
    sweep_points: int = 7
    profile: Path | None = None
    report_only: bool = False
    threads_line: str = ""


def compare(opts: CompareOptions, log: Callable[[str], None]) -> Path:
    """Run (or gather) the comparison and write compare.md; its path. ``log`` says each run as it comes."""
    import dataclasses
    import os

    from common.machine import describe
    from model.compare.compare import compare as run_compare
    from model.compare.compare import saved_results, summary
    from model.compare.compare_report import write_compare_report
    from model.denoiser.config import PRESET_TRAINING
    from model.denoiser.config import preset as make_preset
    from model.evaluation.evaluate import SweepOptions
    from model.training.config_file import load_model_file
    from sensor_sim.profile import load_profile

    cands, seed_list, pairs, step_list = list(opts.candidates), list(opts.seeds), list(opts.settings), opts.step_counts
    if opts.config is not None:
        base, train_fields = load_model_file(opts.config, opts.preset)
    else:
        preset = opts.preset or "tiny"
        base, train_fields = make_preset(preset), dict(PRESET_TRAINING.get(preset, {}))
    if opts.image_size is not None:
        base = dataclasses.replace(base, image_size=opts.image_size)
    given = {"steps": step_list[0] if step_list else None, "batch_size": opts.batch_size, "lr": opts.lr}
    train_fields = {**train_fields, "sample_every": 0, **{k: v for k, v in given.items() if v is not None}}
    train_fields.setdefault("checkpoint_every", train_fields.get("steps", 2000))
    sensor = load_profile(opts.profile) if opts.profile is not None else None
    log(opts.threads_line)
    evaluate_kwargs = dict(
        settings=pairs,
        limit=opts.limit,
        profile=opts.profile,
        sweep=SweepOptions(opts.sweep_poses, opts.sweep_points, pairs[0][0], pairs[0][1]),
    )
    if opts.report_only:  # the runs' saved evaluations, gathered again (nothing trained or evaluated)
        results = saved_results(cands, seed_list, opts.out)
    else:
        results = run_compare(
            cands,
            seed_list,
            base,
            train_fields,
            opts.data,
            opts.out,
            evaluate_kwargs=evaluate_kwargs,
            profile=sensor,
            log=log,
        )
    context = {
        "split": opts.data.resolve().name,
        "training": f"{base.image_size} px, widths {list(base.block_out_channels)}, "
        + ", ".join(
            f"{k} {','.join(map(str, step_list)) if k == 'steps' and len(step_list) > 1 else v}"
            for k, v in train_fields.items()
            if k in ("steps", "batch_size", "lr")
        )
        + "; the seed sets the initial weights, the data order and the noise",
        "evaluation": f"{', '.join(f'{s}:{n}' for s, n in pairs)}, noise seed 0, "
        + (f"at most {opts.limit} frames per part" if opts.limit else "every frame of each part")
        + f"; force sweep at up to {opts.sweep_poses} poses (firm contact, see each report), "
        f"{opts.sweep_points} values",
        "machine": f"{describe()}; load average at the end {os.getloadavg()[0]:.1f}",
        "runs": "each in CANDIDATE/seed-S/ with its report (report/report.md)",
    }
    return write_compare_report(
        summary(results),
        opts.out,
        title=f"{len(cands)} settings × {len(seed_list)} seeds on {opts.data.resolve().name}",
        context=context,
    )
