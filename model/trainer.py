"""Training: a loop that knows the denoiser only through the diffusion loss.

Exact resume: the data order is a function of (seed, step) alone, and a checkpoint
holds the model, its EMA, the optimizer and the noise generator, so a resumed run
takes the same steps with the same losses as an uninterrupted one. Checkpoints are
safetensors (no pickle): tensors in .safetensors files, the rest in JSON.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import torch
from safetensors.torch import load_file, save_file

from dataset.torch_dataset import TactileDataset, to_model_inputs
from model.config import ModelConfig
from model.diffusion import Diffusion
from model.network import ContactDenoiser


@dataclass(frozen=True)
class TrainConfig:
    steps: int = 2000  # optimisation steps in all
    batch_size: int = 16
    lr: float = 2e-4  # Adam, as Palette/SR3
    ema_decay: float = 0.999  # sampling uses the EMA weights
    checkpoint_every: int = 500
    seed: int = 0  # data order and noise


class CheckpointError(ValueError):
    pass


class Trainer:
    def __init__(self, model_cfg: ModelConfig, train_cfg: TrainConfig, split_dir: str | Path, out_dir: str | Path,
                 *, device: str = "cpu", log: Callable[[str], None] = print):
        self.model_cfg, self.cfg = model_cfg, train_cfg
        self.out = Path(out_dir)
        self.device = torch.device(device)
        self.log = log
        torch.manual_seed(train_cfg.seed)  # initial weights
        self.net = ContactDenoiser(model_cfg).to(self.device)
        self.ema = copy.deepcopy(self.net).eval().requires_grad_(False)
        self.opt = torch.optim.Adam(self.net.parameters(), lr=train_cfg.lr)
        self.diffusion = Diffusion(model_cfg)
        self.data = TactileDataset(split_dir, "train", size=model_cfg.image_size)
        if len(self.data) < train_cfg.batch_size:
            raise ValueError(f"{split_dir}: {len(self.data)} training frames, fewer than one batch of {train_cfg.batch_size}")
        self.step = 0
        self.noise = torch.Generator(device=self.device).manual_seed(train_cfg.seed + 1)
        self.losses: list[float] = []

    # -- data order: a pure function of (seed, step) ---------------------------------
    def batch_indices(self, step: int) -> np.ndarray:
        b = self.cfg.batch_size
        per_epoch = len(self.data) // b  # drop the last partial batch
        epoch, i = divmod(step, per_epoch)
        order = np.random.default_rng([self.cfg.seed, epoch]).permutation(len(self.data))
        return order[i * b:(i + 1) * b]

    def _batch(self, step: int) -> dict:
        items = [self.data[int(i)] for i in self.batch_indices(step)]
        batch = {k: torch.stack([it[k] for it in items]) for k in ("condition", "wrench", "tactile")}
        return to_model_inputs(batch, self.device)

    # -- the loop ------------------------------------------------------------------------
    def train(self, until: int | None = None) -> list[float]:
        until = self.cfg.steps if until is None else until
        t0, done = time.perf_counter(), 0
        while self.step < until:
            batch = self._batch(self.step)
            with torch.autocast(self.device.type, enabled=self.device.type == "cuda"):
                loss = self.diffusion.loss(self.net, batch["tactile"], batch["condition"], batch["wrench"],
                                           generator=self.noise)
            self.opt.zero_grad(set_to_none=True)
            loss.backward()
            self.opt.step()
            with torch.no_grad():
                for e, p in zip(self.ema.parameters(), self.net.parameters()):
                    e.lerp_(p, 1.0 - self.cfg.ema_decay)
            self.step += 1
            done += 1
            self.losses.append(float(loss.detach()))
            if self.step % 50 == 0 or self.step == until:
                rate = done * self.cfg.batch_size / (time.perf_counter() - t0)
                self.log(f"step {self.step}/{until}  loss {np.mean(self.losses[-50:]):.4f}  {rate:.1f} images/s")
            if self.step % self.cfg.checkpoint_every == 0:
                self.save()
        return self.losses

    # -- checkpoints -------------------------------------------------------------------
    def save(self) -> Path:
        ck = self.out / "checkpoint"
        ck.mkdir(parents=True, exist_ok=True)
        save_file({k: v.contiguous() for k, v in self.net.state_dict().items()}, str(ck / "model.safetensors"))
        save_file({k: v.contiguous() for k, v in self.ema.state_dict().items()}, str(ck / "ema.safetensors"))
        opt = self.opt.state_dict()
        tensors = {f"{pid}.{key}": v for pid, st in opt["state"].items() for key, v in st.items()
                   if isinstance(v, torch.Tensor)}
        tensors["noise_generator_state"] = self.noise.get_state()
        save_file(tensors, str(ck / "optimizer.safetensors"))
        meta = {"step": self.step, "model": dataclasses.asdict(self.model_cfg), "train": dataclasses.asdict(self.cfg),
                "param_groups": opt["param_groups"], "losses": self.losses,
                # what inference needs to condition like training did
                "wrench_mean": self.data.manifest["wrench_mean"], "wrench_std": self.data.manifest["wrench_std"],
                "mm_per_px": self.data.mm_per_px[0]}
        (ck / "state.json").write_text(json.dumps(meta))
        return ck

    def resume(self) -> None:
        ck = self.out / "checkpoint"
        if not (ck / "state.json").exists():
            raise CheckpointError(f"{ck}: no checkpoint to resume")
        meta = json.loads((ck / "state.json").read_text())
        mine = json.loads(json.dumps(dataclasses.asdict(self.model_cfg)))
        if meta["model"] != mine:
            diff = {k: (meta["model"].get(k), v) for k, v in mine.items() if meta["model"].get(k) != v}
            raise CheckpointError(f"{ck}: trained with a different model config (checkpoint vs now: {diff})")
        try:
            self.net.load_state_dict(load_file(str(ck / "model.safetensors"), device=str(self.device)))
            self.ema.load_state_dict(load_file(str(ck / "ema.safetensors"), device=str(self.device)))
        except RuntimeError as exc:
            raise CheckpointError(f"{ck}: weights do not fit this model: {str(exc).splitlines()[0]}") from exc
        tensors = load_file(str(ck / "optimizer.safetensors"))
        self.noise.set_state(tensors.pop("noise_generator_state"))
        state: dict = {}
        for name, v in tensors.items():
            pid, key = name.split(".", 1)
            state.setdefault(int(pid), {})[key] = v.to(self.device) if key != "step" else v
        self.opt.load_state_dict({"state": state, "param_groups": meta["param_groups"]})
        self.step = meta["step"]
        self.losses = list(meta["losses"])
