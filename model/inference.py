"""Load a trained run for generation: the EMA weights and the conditioning statistics."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch
from safetensors.torch import load_file

from dataset.condition import normalise_wrench, place_object
from dataset.torch_dataset import image_to_tensor, scale_images, tensor_to_image
from model.config import ModelConfig
from model.diffusion import Diffusion
from model.network import ContactDenoiser
from model.trainer import CheckpointError


@dataclass
class TrainedModel:
    net: ContactDenoiser
    diffusion: Diffusion
    cfg: ModelConfig
    wrench_mean: np.ndarray
    wrench_std: np.ndarray
    mm_per_px: float
    device: torch.device

    @classmethod
    def load(cls, run_dir: str | Path, device: str = "cpu") -> "TrainedModel":
        ck = Path(run_dir) / "checkpoint"
        if not (ck / "state.json").exists():
            raise CheckpointError(f"{ck}: no checkpoint (train one with `train --out {run_dir}`)")
        meta = json.loads((ck / "state.json").read_text())
        missing = [k for k in ("wrench_mean", "wrench_std", "mm_per_px") if k not in meta]
        if missing:
            raise CheckpointError(f"{ck}: has no conditioning statistics ({', '.join(missing)}): it predates them; "
                                  "train on (with --resume) to write a complete checkpoint")
        cfg = ModelConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in meta["model"].items()})
        net = ContactDenoiser(cfg)
        try:
            net.load_state_dict(load_file(str(ck / "ema.safetensors")))
        except RuntimeError as exc:
            raise CheckpointError(f"{ck}: EMA weights do not fit the saved config: {str(exc).splitlines()[0]}") from exc
        dev = torch.device(device)
        return cls(net.to(dev).eval(), Diffusion(cfg), cfg, np.asarray(meta["wrench_mean"]),
                   np.asarray(meta["wrench_std"]), float(meta["mm_per_px"]), dev)

    def generate(self, object_bgr: np.ndarray, wrench: np.ndarray, pose=(0.0, 0.0, 0.0), *, steps: int = 50,
                 sampler: str = "ddim", seed: int = 0, guidance: float = 1.0) -> np.ndarray:
        """One tactile frame (BGR uint8, S×S) for an object image, a wrench (N, N·mm) and a pose (x, y mm, θ deg)."""
        wrench = np.asarray(wrench, dtype=np.float64)
        if wrench.shape != (6,) or not np.all(np.isfinite(wrench)):
            raise ValueError(f"wrench must be six finite numbers Fx,Fy,Fz (N),Mx,My,Mz (N·mm), got {wrench.tolist()}")
        s = self.cfg.image_size
        square = cv2.resize(object_bgr, (max(object_bgr.shape[:2]),) * 2)
        placed = place_object(square, pose[0], pose[1], pose[2], self.mm_per_px * s / square.shape[0], size=s)
        cond = scale_images(image_to_tensor(placed)[None])
        w = torch.from_numpy(normalise_wrench(wrench, self.wrench_mean, self.wrench_std).astype(np.float32))[None]
        g = torch.Generator(device=self.device).manual_seed(seed)
        out = self.diffusion.sample(self.net, cond.to(self.device), w.to(self.device), steps=steps, sampler=sampler,
                                    guidance=guidance, generator=g)[0]
        return tensor_to_image(out)
