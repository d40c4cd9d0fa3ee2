"""Evaluate a trained run on a split's test part: the paper's metrics, per sampler setting.

For each (sampler, steps) setting: MSE, MAE, SSIM, PSNR (model/metrics.py), the
marker displacement error for marker sensors, and the seconds per generated image.
Written as a Markdown report with the paper's rows for comparison.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from dataset.torch_dataset import TactileDataset, scale_images, tensor_to_image
from model.inference import TrainedModel
from model.markers import marker_error
from model.metrics import image_metrics

PAPER_ROWS = [  # shared/REFERENCE.md §2, real data, 0–255 scale
    ("TACTO (RGB light)", 201.87, 10.31, 0.80, 25.43),
    ("Taxim (RGB light)", 56.715, 5.14, 0.88, 31.12),
    ("FOTS (RGB light)", 53.267, 4.91, 0.89, 32.30),
    ("paper, RGB light", 21.00, 3.39, 0.97, 36.62),
    ("paper, RGB light + markers", 28.02, 3.24, 0.95, 34.28),
    ("paper, white light + markers", 67.09, 5.27, 0.81, 30.91),
]


@dataclass
class Row:
    setting: str
    mse: float
    mae: float
    ssim: float
    psnr: float
    marker_px: float | None
    seconds_per_image: float
    images: int


def evaluate(run_dir: str | Path, split_dir: str | Path, *, part: str = "test", settings=(("ddim", 50),),
             limit: int | None = None, seed: int = 0, markers: bool = False, device: str = "cpu") -> list[Row]:
    model = TrainedModel.load(run_dir, device=device)
    data = TactileDataset(split_dir, part, size=model.cfg.image_size)
    n = len(data) if limit is None else min(limit, len(data))
    if n == 0:
        raise ValueError(f"{split_dir}: the {part} part is empty")
    items = [data[i] for i in range(n)]
    cond = scale_images(torch.stack([it["condition"] for it in items]).to(model.device))
    wrench = torch.stack([it["wrench"] for it in items]).to(model.device)
    real = [it["tactile"].numpy().transpose(1, 2, 0)[..., ::-1] for it in items]
    rows = []
    for sampler, steps in settings:
        g = torch.Generator(device=model.device).manual_seed(seed)
        t0 = time.perf_counter()
        out = model.diffusion.sample(model.net, cond, wrench, steps=steps, sampler=sampler, generator=g)
        seconds = (time.perf_counter() - t0) / n
        generated = [tensor_to_image(x) for x in out]
        metrics = [image_metrics(r, gimg) for r, gimg in zip(real, generated)]
        marker = None
        if markers:
            marker = float(np.mean([marker_error(r, gimg).per_marker_px for r, gimg in zip(real, generated)]))
        rows.append(Row(f"{sampler}, {steps} steps", *(float(np.mean([m[k] for m in metrics]))
                                                      for k in ("mse", "mae", "ssim", "psnr")), marker, seconds, n))
    return rows


def report(rows: list[Row], out: str | Path, *, title: str) -> Path:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    lines = [f"# {title}", "", "Metrics as shared/REFERENCE.md §3 defines them (0–255 scale, all channels).", "",
             "| method | MSE | MAE | SSIM | PSNR | marker px/marker | s / image |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        mk = "—" if r.marker_px is None else f"{r.marker_px:.2f}"
        lines.append(f"| this model ({r.setting}, {r.images} images) | {r.mse:.2f} | {r.mae:.2f} | {r.ssim:.3f} | "
                     f"{r.psnr:.2f} | {mk} | {r.seconds_per_image:.3f} |")
    for name, mse_, mae_, ssim_, psnr_ in PAPER_ROWS:
        lines.append(f"| {name} (paper's table, real data) | {mse_} | {mae_} | {ssim_} | {psnr_} | — | — |")
    (out / "report.md").write_text("\n".join(lines) + "\n")
    (out / "metrics.json").write_text(json.dumps([r.__dict__ for r in rows], indent=2) + "\n")
    return out / "report.md"
