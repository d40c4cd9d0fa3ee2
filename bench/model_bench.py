"""Training and sampling throughput of the denoiser, per preset and image size.

    .venv/bin/python bench/model_bench.py [--preset tiny | --config FILE] [--size 32] [--batch 16] [--steps 10,25,50]
                                          [--device cpu|cuda] [--precision no|bf16|fp16] [--guidance 1]
                                          [--threads N]

Training: images/s of optimisation steps (forward, the diffusion loss of the configured
target, backward, Adam, EMA) on random tensors, so the number is the model's, not the data
loader's (bench/dataset_bench.py measures that). Sampling: images/s and seconds per image
for each sampler and step count, a batch at a time, as `evaluate` generates (with
--guidance w ≠ 1, each step is one forward pass over twice the batch).
"""

from __future__ import annotations

import argparse
import os
import platform
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="tiny", help="tiny or paper (default tiny)")
    ap.add_argument("--config", default=None, help="a model TOML (train --config); overrides --preset")
    ap.add_argument("--size", type=int, default=None, help="image size, px (default: the preset's)")
    ap.add_argument("--conditioning", default=None, help="plane, embedding or plane+embedding (default: the preset's)")
    ap.add_argument("--batch", type=int, default=16, help="training batch (default 16)")
    ap.add_argument("--sample-batch", type=int, default=64, help="sampling batch (default 64)")
    ap.add_argument("--train-steps", type=int, default=20, help="timed training steps (default 20)")
    ap.add_argument("--steps", default="10,25,50", help="sampler step counts (default 10,25,50)")
    ap.add_argument("--samplers", default="ddim,dpm", help="samplers (default ddim,dpm)")
    ap.add_argument("--device", default="cuda" if _cuda() else "cpu")
    ap.add_argument("--precision", default="no", help="training autocast: no, bf16 or fp16 (default no)")
    ap.add_argument("--guidance", type=float, default=1.0, help="classifier-free guidance weight (default 1: none)")
    ap.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's choice)")
    args = ap.parse_args()

    import torch

    from model.denoiser.config import preset
    from model.denoiser.diffusion import Diffusion
    from model.denoiser.registry import build_network

    if args.threads:
        torch.set_num_threads(args.threads)

    over = {k: v for k, v in (("image_size", args.size), ("conditioning", args.conditioning)) if v is not None}
    if args.config:
        import dataclasses

        from model.training.config_file import load_model_file

        cfg = dataclasses.replace(load_model_file(args.config)[0], **over)
    else:
        cfg = preset(args.preset, **over)
    dev = torch.device(args.device)
    torch.manual_seed(0)
    net = build_network(cfg).to(dev)
    ema = build_network(cfg).to(dev).eval().requires_grad_(False)
    opt = torch.optim.Adam(net.parameters(), lr=2e-4)
    diff = Diffusion(cfg)
    s, b = cfg.image_size, args.batch
    tactile, cond = torch.rand(b, 3, s, s, device=dev) * 2 - 1, torch.rand(b, 3, s, s, device=dev) * 2 - 1
    wrench = torch.randn(b, 6, device=dev)
    dtype = {"bf16": torch.bfloat16, "fp16": torch.float16}.get(args.precision)

    def train_step():
        with torch.autocast(dev.type, dtype=dtype, enabled=dtype is not None):
            loss = diff.loss(net, tactile, cond, wrench)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        with torch.no_grad():
            for e, p in zip(ema.parameters(), net.parameters()):
                e.lerp_(p, 0.001)

    def sync():
        if dev.type == "cuda":
            torch.cuda.synchronize()

    for _ in range(3):
        train_step()
    sync()
    t0 = time.perf_counter()
    for _ in range(args.train_steps):
        train_step()
    sync()
    train_s = (time.perf_counter() - t0) / args.train_steps
    params = sum(p.numel() for p in net.parameters())

    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"torch {torch.__version__}, device {dev}"
        + (f" ({torch.cuda.get_device_name()})" if dev.type == "cuda" else f", {torch.get_num_threads()} threads")
    )
    print(
        f"model: {args.config or 'preset ' + args.preset}, {cfg.network}, {s} px, "
        f"widths {list(cfg.block_out_channels)}, {cfg.conditioning}, {params / 1e6:.2f} M parameters"
    )
    print(
        f"\ntraining, batch {b}, precision {args.precision}: {train_s * 1e3:.1f} ms/step, {b / train_s:.1f} images/s\n"
    )
    print(f"| sampler | steps | s / image | images/s (batch {args.sample_batch}, guidance {args.guidance:g}) |")
    print("|---|---|---|---|")
    sb = args.sample_batch
    scond = torch.rand(sb, 3, s, s, device=dev) * 2 - 1
    swrench = torch.randn(sb, 6, device=dev)
    ema.eval()
    diff.sample(ema, scond[:2], swrench[:2], steps=2)  # warm-up
    for sampler in args.samplers.split(","):
        for steps in (int(x) for x in args.steps.split(",")):
            sync()
            t0 = time.perf_counter()
            diff.sample(ema, scond, swrench, steps=steps, sampler=sampler, guidance=args.guidance)
            sync()
            dt = time.perf_counter() - t0
            print(f"| {sampler} | {steps} | {dt / sb:.4f} | {sb / dt:.1f} |")


def _cuda() -> bool:
    try:
        import torch

        return torch.cuda.is_available()
    except ImportError:
        return False


if __name__ == "__main__":
    main()
