"""Which training settings give the best first report per minute (issue 17).

    nice -n 10 .venv/bin/python bench/first_result_bench.py [--runs A.h5 B.h5] [--work DIR]
        [--eval-frames 150] [--sampler ddim:10] [--threads 1] [--only NAME,NAME] [--resume]
    .venv/bin/python bench/first_result_bench.py --main-job-vs OLD_TREE [--rounds 2] [--work DIR]
        (the main job as typed, this checkout against another, in turn: bench/main_job_side_by_side.py)

One split (8:2 by frame, seed 0, as the main job makes) of the main job's two objects; for
each candidate (image size, batch, learning rate, model widths) one training run, evaluated
at several step counts along the way on the same held-out frames with the same sampler. A
constant learning rate and a step-seeded data order and noise make the first N steps of a
long run exactly an N-step run, so one run gives the whole quality-against-time curve.

Each row: seconds of training (wall and this process's CPU), seconds to generate the
evaluated frames, and the report's metrics (MSE, SSIM, PSNR on the 0–255 scale, at the
model's own size), and the share of the contact signal explained: 1 − MSE / MSE of the
no-contact background frame (the run's reference frame), the baseline a model must beat
to have learnt anything; the mean training frame and the simulator's physics render are
two more baselines at each size. Results are appended to WORK/results.jsonl as they come
(``--resume`` skips rows already there) and printed as a Markdown table at the end.

Torch threads: one by default (``--threads``), so a shared machine's load slows each
candidate alike; the thread count itself is measured separately (docs/benchmarks.md).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

DEFAULT_RUNS = ("/work/data/sim/rgb/sphere10mm.h5", "/work/data/sim/rgb/circle8mm.h5")


@dataclass(frozen=True)
class Candidate:
    name: str
    size: int  # image side, px
    batch: int
    lr: float
    evals: tuple[int, ...]  # steps at which the EMA weights are evaluated; the last ends the run
    widths: tuple[int, ...] = (32, 64, 64)  # the tiny preset's


CANDIDATES = (
    Candidate("32px-b16-lr2e-3", 32, 16, 2e-3, (150, 300, 450, 600, 900)),
    Candidate("32px-b16-lr1e-3", 32, 16, 1e-3, (300, 600, 1500)),  # today's main job at 1500
    Candidate("32px-b32-lr2e-3", 32, 32, 2e-3, (150, 300)),
    Candidate("48px-b16-lr2e-3", 48, 16, 2e-3, (200, 400)),
    Candidate("64px-b16-lr2e-3", 64, 16, 2e-3, (150, 300)),
    Candidate("32px-b16-lr4e-3", 32, 16, 4e-3, (150, 300, 450)),
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", nargs="+", default=list(DEFAULT_RUNS), help="run files (default: the main job's two)")
    ap.add_argument("--work", default="/tmp/first-result-bench", help="folder for the split and results")
    ap.add_argument("--eval-frames", type=int, default=150, help="held-out frames evaluated (default 150)")
    ap.add_argument("--sampler", default="ddim:10", help="sampler:steps of the evaluation (default ddim:10)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    ap.add_argument("--only", default="", help="comma-separated candidate names (default: all)")
    ap.add_argument("--resume", action="store_true", help="skip candidates already in WORK/results.jsonl")
    ap.add_argument(
        "--measure-threads",
        type=int,
        default=0,
        metavar="ROUNDS",
        help="instead: ROUNDS of training and sampling bursts at 1 then 2 threads (model/denoiser/threads.py's rule)",
    )
    ap.add_argument("--busy", action="store_true", help="with --measure-threads: keep one core busy meanwhile")
    ap.add_argument(
        "--main-job-vs",
        type=Path,
        metavar="OLD_TREE",
        help="instead: `bash scripts/main_job.sh` of this checkout and of OLD_TREE in turn",
    )
    ap.add_argument("--rounds", type=int, default=2, help="with --main-job-vs: runs of each tree (default 2)")
    args = ap.parse_args()
    if args.main_job_vs is not None:
        from main_job_side_by_side import side_by_side

        if args.rounds < 1:
            ap.error("--rounds must be at least 1")
        side_by_side(args.main_job_vs, Path(args.work), args.rounds)
        return
    if args.measure_threads:
        measure_threads(args.runs, Path(args.work), args.measure_threads, args.busy)
        return
    if args.eval_frames < 1 or args.threads < 1:
        ap.error("--eval-frames and --threads must be at least 1")
    sampler, _, steps_text = args.sampler.partition(":")
    if not steps_text.isdigit() or int(steps_text) < 1:
        ap.error(f"--sampler: expected sampler:steps, got {args.sampler!r}")

    import torch

    from common.machine import describe
    from dataset.split import make_split

    torch.set_num_threads(args.threads)
    work = Path(args.work)
    split = work / "split"
    if not (split / "split.json").exists():
        make_split(args.runs, "8:2", split, seed=0)
    results = work / "results.jsonl"
    done = {json.loads(line)["name"] for line in results.read_text().splitlines()} if results.exists() else set()
    print(
        f"machine: {describe()}, torch {torch.__version__}, {args.threads} thread(s); "
        f"load average at the start {os.getloadavg()[0]:.1f}"
    )
    wanted = [c for c in CANDIDATES if not args.only or c.name in args.only.split(",")]
    baselines: dict[int, list[dict]] = {}
    for cand in wanted:
        if args.resume and cand.name in done:
            continue
        if cand.size not in baselines:
            baselines[cand.size] = baseline_rows(split, cand.size, args.eval_frames)
            _append(results, baselines[cand.size])
        rows = run_candidate(cand, split, work, args.eval_frames, sampler, int(steps_text))
        _append(results, rows)
    print_table([json.loads(line) for line in results.read_text().splitlines()])


def measure_threads(runs: list[str], work: Path, rounds: int, busy: bool) -> None:
    """Images/s of real training steps (32 px, batch 16, the split's items) and of DDIM-10 sampling
    (batch 64), at 1 and 2 torch threads in turn, beside how many other processes were running."""
    import subprocess
    import sys

    import torch

    from dataset.split import make_split
    from model.denoiser.config import preset
    from model.denoiser.threads import running_now
    from model.generation.inference import generate_items
    from model.training.build import build
    from model.training.trainer import TrainConfig

    split = work / "split"
    if not (split / "split.json").exists():
        make_split(runs, "8:2", split, seed=0)
    spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if busy else None
    try:
        cfg = TrainConfig(steps=10**6, batch_size=16, lr=2e-3, sample_every=0, checkpoint_every=10**9)
        trainer = build(preset("tiny"), cfg, split, work / "threads", device="cpu", log=lambda line: None)
        _, items, _ = eval_items(split, 32, 64)
        trainer.train(until=5)  # warm-up: every item of the first steps read, first-call costs paid
        print("\n| threads | other processes running | training images/s | sampling images/s (DDIM 10) |")
        print("|---|---|---|---|")
        for _ in range(rounds):
            for n in (1, 2):
                torch.set_num_threads(n)
                others = max(0.0, (running_now() or 1.0) - 1.0)
                t0 = time.perf_counter()
                trainer.train(until=trainer.step + 20)
                train_rate = 20 * 16 / (time.perf_counter() - t0)
                t0 = time.perf_counter()
                list(generate_items(trainer.ema, trainer.diffusion, items, "cpu", steps=10, sampler="ddim", seed=0))
                sample_rate = len(items) / (time.perf_counter() - t0)
                print(f"| {n} | {others:.1f} | {train_rate:.1f} | {sample_rate:.1f} |", flush=True)
    finally:
        if spinner is not None:
            spinner.kill()
            spinner.wait()


def _append(path: Path, rows: list[dict]) -> None:
    with path.open("a") as fh:
        for row in rows:
            fh.write(json.dumps(row) + "\n")
            print(_line(row), flush=True)


def eval_items(split: Path, size: int, n: int) -> tuple[Any, list[dict], list[np.ndarray]]:
    from dataset.torch_dataset import TactileDataset, spread, uint8_tensor_to_image

    data = TactileDataset(split, "test", size=size)
    items = [data[int(i)] for i in spread(len(data), n)]
    return data, items, [uint8_tensor_to_image(it["tactile"]) for it in items]


def scores(real: list[np.ndarray], made: list[np.ndarray]) -> dict[str, float]:
    from model.evaluation.metrics import image_metrics

    m = [image_metrics(r, g) for r, g in zip(real, made)]
    return {k: float(np.mean([x[k] for x in m])) for k in ("mse", "mae", "ssim", "psnr")}


def baseline_rows(split: Path, size: int, n: int) -> list[dict]:
    """Background (the run's no-contact frame), mean training frame, physics render: at ``size``."""
    import cv2
    import h5py

    from acquisition import schema as S
    from dataset.torch_dataset import TactileDataset, spread, uint8_tensor_to_image
    from model.conditioning.baseline import render_frames

    data, items, real = eval_items(split, size, n)
    refs = {}
    for run, path in enumerate(data.runs):
        with h5py.File(path, "r", swmr=True) as f:
            refs[run] = cv2.resize(f[S.REFERENCE_FRAME][()], (size, size), interpolation=cv2.INTER_AREA)
    train = TactileDataset(split, "train", size=size)
    mean = np.mean(
        [uint8_tensor_to_image(train[int(i)]["tactile"]).astype(np.float64) for i in spread(len(train), 300)], axis=0
    )
    rows = [
        {"name": f"background {size}px", "size": size, **scores(real, [refs[int(it["run"])] for it in items])},
        {"name": f"mean frame {size}px", "size": size, **scores(real, [mean.round().astype(np.uint8)] * len(real))},
    ]
    t0 = time.perf_counter()
    made, _ = render_frames(
        data.runs,
        np.array([[it["run"], it["frame"]] for it in items]),
        np.stack([it["pose"].numpy() for it in items]),
        size,
    )
    rows.append(
        {
            "name": f"physics render {size}px",
            "size": size,
            "eval_s": time.perf_counter() - t0,
            **scores(real, made),
        }
    )
    return rows


def run_candidate(cand: Candidate, split: Path, work: Path, n: int, sampler: str, steps: int) -> list[dict]:
    import dataclasses

    from model.denoiser.config import preset
    from model.generation.inference import generate_items
    from model.training.build import build
    from model.training.trainer import TrainConfig

    model_cfg = dataclasses.replace(preset("tiny"), image_size=cand.size, block_out_channels=cand.widths)
    train_cfg = TrainConfig(
        steps=cand.evals[-1], batch_size=cand.batch, lr=cand.lr, sample_every=0, checkpoint_every=10**9
    )
    trainer = build(model_cfg, train_cfg, split, work / cand.name, device="cpu", log=lambda line: None)
    _, items, real = eval_items(split, cand.size, n)
    rows, wall, cpu = [], 0.0, 0.0
    for until in cand.evals:
        t0, c0 = time.perf_counter(), time.process_time()
        trainer.train(until=until)
        wall += time.perf_counter() - t0
        cpu += time.process_time() - c0
        t0 = time.perf_counter()
        made = list(
            generate_items(trainer.ema, trainer.diffusion, items, trainer.device, steps=steps, sampler=sampler, seed=0)
        )
        eval_s = time.perf_counter() - t0
        loss = float(np.mean(trainer.losses[-50:]))
        rows.append(
            {
                "name": cand.name,
                "size": cand.size,
                "batch": cand.batch,
                "lr": cand.lr,
                "steps": until,
                "images": until * cand.batch,
                "train_s": wall,
                "train_cpu_s": cpu,
                "eval_s": eval_s,
                "loss": loss,
                "load": os.getloadavg()[0],
                **scores(real, made),
            }
        )
        _append(work / "progress.jsonl", rows[-1:])
    return rows


def _line(row: dict) -> str:
    keys = ("steps", "train_s", "train_cpu_s", "eval_s", "mse", "ssim", "psnr")
    return row["name"] + ": " + ", ".join(f"{k} {row[k]:.4g}" for k in keys if k in row)


def print_table(rows: list[dict]) -> None:
    """Markdown: per candidate and step count, cost and quality; ``explained`` = 1 − MSE / MSE of
    the background frame at the same size (comparable across sizes). Cost: this process's CPU
    seconds of training (what a shared machine's load inflates least) and the wall seconds."""
    seen, unique = set(), []
    for r in rows:  # a resumed run may hold a row twice: the first counts
        key = (r["name"], r.get("steps"))
        if key not in seen:
            seen.add(key)
            unique.append(r)
    background = {r["size"]: r["mse"] for r in unique if r["name"].startswith("background")}
    print("\n| candidate | steps | images | train CPU s | train wall s | eval wall s | MSE | SSIM | PSNR | explained |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in unique:
        bg = background.get(r["size"])
        explained = f"{1 - r['mse'] / bg:.3f}" if bg else "—"
        if "steps" in r:
            cost = f"{r['steps']} | {r['images']} | {r['train_cpu_s']:.0f} | {r['train_s']:.0f} | {r['eval_s']:.0f}"
        else:
            cost = "— | — | — | — | " + (f"{r['eval_s']:.0f}" if "eval_s" in r else "—")
        print(f"| {r['name']} | {cost} | {r['mse']:.2f} | {r['ssim']:.4f} | {r['psnr']:.2f} | {explained} |")


if __name__ == "__main__":
    main()
