"""Which conditioning (plane H(F), embedding, physics render, combinations) or network target (y₀, ε, v) is better.

    .venv/bin/python bench/conditioning_bench.py --split DIR [--vary conditioning|prediction]
        [--conditionings plane,embedding,plane+embedding,physics,physics+plane+embedding]
        [--size 32] [--steps 1000] [--eval-frames 200] [--part test] [--threads 1]

Trains one model per choice on the same split with the same seed, steps and batch
(same data order, same noise), then evaluates each on the same frames of ``--part`` (a
held-out object's part for the question "does it generalise") with the same sampler and
seed, beside the physics render itself. Prints one table (MSE, MAE, SSIM, PSNR, marker
error for marker sensors, s/image); the defaults in model/denoiser/config.py follow it.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--split", type=Path, required=True, help="a split directory from `dataset split`")
    ap.add_argument(
        "--vary",
        choices=("conditioning", "prediction"),
        default="conditioning",
        help="what differs between the models (default conditioning)",
    )
    ap.add_argument(
        "--conditionings",
        default="plane,embedding,plane+embedding,physics,physics+plane+embedding",
        help="comma-separated conditionings compared when varying conditioning, each optionally with :residual "
        "(target physics_residual; default: the five above)",
    )
    ap.add_argument("--part", default="test", help="the split part evaluated (default test)")
    ap.add_argument("--threads", type=int, default=None, help="torch threads (default: torch's)")
    ap.add_argument("--size", type=int, default=32, help="image size, px (default 32)")
    ap.add_argument("--steps", type=int, default=1000, help="training steps per model (default 1000)")
    ap.add_argument("--batch-size", type=int, default=16, help="images per step (default 16)")
    ap.add_argument("--eval-frames", type=int, default=200, help="test frames evaluated (default 200)")
    ap.add_argument("--sampler", default="ddim:20", help="sampler:steps for evaluation (default ddim:20)")
    ap.add_argument(
        "--prediction", default=None, help="network target when varying conditioning (default: the tiny preset's)"
    )
    ap.add_argument("--lr", type=float, default=None, help="learning rate (default: the tiny preset's)")
    ap.add_argument("--out", type=Path, default=None, help="keep the runs here (default: a temporary folder)")
    args = ap.parse_args()

    import torch

    from model.denoiser.config import PREDICTIONS, PRESET_TRAINING, preset
    from model.evaluation.evaluate import evaluate
    from model.training.build import build
    from model.training.trainer import TrainConfig

    if args.threads:
        torch.set_num_threads(args.threads)
    sampler, steps = args.sampler.split(":")
    out = args.out or Path(tempfile.mkdtemp(prefix="conditioning-"))
    rows = []
    baseline = None
    choices = args.conditionings.split(",") if args.vary == "conditioning" else PREDICTIONS
    for choice in choices:
        run = out / choice.replace("+", "_").replace(":", "-")
        # "CONDITIONING:residual" trains on the frame's difference from the physics render (target physics_residual)
        name, _, residual = choice.partition(":")
        over = {args.vary: name}
        if residual:
            if residual != "residual" or args.vary != "conditioning":
                raise SystemExit(f"--conditionings: {choice!r}: only CONDITIONING:residual is understood")
            over["target"] = "physics_residual"
        if args.vary == "conditioning" and args.prediction:
            over["prediction"] = args.prediction
        cfg = preset("tiny", image_size=args.size, **over)
        lr = args.lr or PRESET_TRAINING["tiny"]["lr"]
        t0 = time.perf_counter()
        trainer = build(
            cfg,
            TrainConfig(
                steps=args.steps, batch_size=args.batch_size, checkpoint_every=args.steps, lr=lr, sample_every=0
            ),
            args.split,
            run,
            log=lambda line, c=choice: print(f"  [{c}] {line}", flush=True),
        )
        setup_s = time.perf_counter() - t0  # the physics render cache, when built now
        t0 = time.perf_counter()
        losses = trainer.train()
        train_s = time.perf_counter() - t0
        trainer.save()
        params = sum(p.numel() for p in trainer.net.parameters())
        ev = evaluate(
            run,
            args.split,
            part=args.part,
            settings=[(sampler, int(steps))],
            limit=args.eval_frames,
            baseline=baseline is None,
        )
        baseline = baseline or ev.baseline or False
        rows.append((choice, params, sum(losses[-100:]) / len(losses[-100:]), train_s, setup_s, ev.rows[0]))

    print(
        f"\nmachine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, torch "
        f"{torch.get_num_threads()} thread(s), load average now {os.getloadavg()[0]:.1f}; "
        f"split {args.split}; {args.size} px, {args.steps} steps x {args.batch_size}, "
        f"{'prediction ' + cfg.prediction if args.vary == 'conditioning' else 'conditioning ' + cfg.conditioning}, "
        f"lr {lr:g}; eval {rows[0][-1].images} frames of part {args.part!r} with {sampler} {steps} steps"
    )
    print(
        f"| {args.vary} | parameters | final loss | train s (+ render cache s) | MSE | MAE | SSIM | PSNR "
        "| marker px per marker | s / image |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for choice, params, loss, train_s, setup_s, r in rows:
        print(
            f"| {choice} | {params / 1e6:.2f} M | {loss:.4f} | {train_s:.0f}"
            f"{f' (+ {setup_s:.0f})' if setup_s >= 1 else ''} | {_cells(r)} |"
        )
    if baseline:
        print(f"| physics render alone (the run's background) | — | — | — | {_cells(baseline)} |")


def _cells(r) -> str:
    marker = "—" if r.marker_px is None else f"{r.marker_px:.2f}"
    return f"{r.mse:.2f} | {r.mae:.2f} | {r.ssim:.3f} | {r.psnr:.2f} | {marker} | {r.seconds_per_image:.4f}"


if __name__ == "__main__":
    main()
