"""Which wrench conditioning (plane H(F), embedding, both) or network target (y₀, ε, v) is better.

    .venv/bin/python bench/conditioning_bench.py --split DIR [--vary conditioning|prediction]
                                                 [--size 32] [--steps 1000] [--eval-frames 200]

Trains one model per choice on the same split with the same seed, steps and batch
(same data order, same noise), then evaluates each on the same test frames with the
same sampler and seed. Prints a table; the defaults in model/config.py follow it.
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

    from model.build import build
    from model.config import CONDITIONINGS, PREDICTIONS, PRESET_TRAINING, preset
    from model.evaluate import evaluate
    from model.trainer import TrainConfig

    sampler, steps = args.sampler.split(":")
    out = args.out or Path(tempfile.mkdtemp(prefix="conditioning-"))
    rows = []
    choices = CONDITIONINGS if args.vary == "conditioning" else PREDICTIONS
    for choice in choices:
        run = out / choice.replace("+", "_")
        over = {args.vary: choice}
        if args.vary == "conditioning" and args.prediction:
            over["prediction"] = args.prediction
        cfg = preset("tiny", image_size=args.size, **over)
        lr = args.lr or PRESET_TRAINING["tiny"]["lr"]
        trainer = build(
            cfg,
            TrainConfig(
                steps=args.steps, batch_size=args.batch_size, checkpoint_every=args.steps, lr=lr, sample_every=0
            ),
            args.split,
            run,
            log=lambda line, c=choice: print(f"  [{c}] {line}", flush=True),
        )
        t0 = time.perf_counter()
        losses = trainer.train()
        train_s = time.perf_counter() - t0
        trainer.save()
        params = sum(p.numel() for p in trainer.net.parameters())
        (row,) = evaluate(
            run, args.split, settings=[(sampler, int(steps))], limit=args.eval_frames, baseline=False
        ).rows
        rows.append((choice, params, sum(losses[-100:]) / len(losses[-100:]), train_s, row))

    print(
        f"\nmachine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
        f"split {args.split}; {args.size} px, {args.steps} steps x {args.batch_size}, "
        f"{'prediction ' + cfg.prediction if args.vary == 'conditioning' else 'conditioning ' + cfg.conditioning}, "
        f"lr {lr:g}; eval {args.eval_frames} test frames with {sampler} {steps} steps"
    )
    print(f"| {args.vary} | parameters | final loss | train s | MSE | MAE | SSIM | PSNR |")
    print("|---|---|---|---|---|---|---|---|")
    for choice, params, loss, train_s, r in rows:
        print(
            f"| {choice} | {params / 1e6:.2f} M | {loss:.4f} | {train_s:.0f} | {r.mse:.2f} | {r.mae:.2f} | "
            f"{r.ssim:.3f} | {r.psnr:.2f} |"
        )


if __name__ == "__main__":
    main()
