"""Training: a loop that knows the denoiser only through the diffusion loss.

Exact resume: the data order is a function of (seed, step) alone, and a checkpoint
holds the model, its EMA, the optimizer and the noise generator, so a resumed run
takes the same steps with the same losses as an uninterrupted one. Checkpoints are
safetensors (no pickle): tensors in .safetensors files, the rest in JSON.

Several GPUs or nodes: ``accelerate launch -m cli.model_app ...`` (or ``accelerate launch
$(which train) ...``) runs this same loop in each process; each takes its share of
the step's batch (the global batch and its order are the single-process ones), the
gradients are averaged by accelerate, and the main process logs, samples and saves.
Mixed precision (bf16, or fp16 with loss scaling) on CUDA.
"""

from __future__ import annotations

import copy
import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import torch

from dataset.torch_dataset import TactileDataset, to_model_inputs
from model import checkpoint as C
from model.checkpoint import CheckpointError
from model.config import ModelConfig
from model.diffusion import Diffusion
from model.network import ContactDenoiser


@dataclass(frozen=True)
class TrainConfig:
    steps: int = 2000  # optimisation steps in all
    batch_size: int = 16
    lr: float = 2e-4  # Adam, as Palette/SR3 (presets set their own: model/config.py PRESET_TRAINING)
    ema_decay: float = 0.999  # sampling uses the EMA weights
    checkpoint_every: int = 500
    sample_every: int = 500  # validation samples saved as PNG this often (0: never)
    samples: int = 4  # validation frames in each PNG
    sample_steps: int = 25  # DDIM steps for the validation samples
    seed: int = 0  # data order and noise
    mixed_precision: str = "auto"  # auto (bf16 on CUDA when supported, else fp16; none on CPU) | no | fp16 | bf16


class Trainer:
    def __init__(self, model_cfg: ModelConfig, train_cfg: TrainConfig, split_dir: str | Path, out_dir: str | Path,
                 *, device: str | None = None, log: Callable[[str], None] = print):
        from accelerate import Accelerator

        self.model_cfg, self.cfg = model_cfg, train_cfg
        self.out = Path(out_dir)
        self.acc = Accelerator(cpu=device == "cpu", mixed_precision=_precision(train_cfg.mixed_precision, device))
        self.device = self.acc.device
        self.main = self.acc.is_main_process
        self.log = log if self.main else (lambda line: None)
        torch.manual_seed(train_cfg.seed)  # initial weights: the same in every process
        net = ContactDenoiser(model_cfg).to(self.device)
        self.ema = copy.deepcopy(net).eval().requires_grad_(False)
        opt = torch.optim.Adam(net.parameters(), lr=train_cfg.lr)
        self.net, self.opt = self.acc.prepare(net, opt)
        self.diffusion = Diffusion(model_cfg)
        self.data = TactileDataset(split_dir, "train", size=model_cfg.image_size)
        if len(self.data) < train_cfg.batch_size:
            raise ValueError(f"{split_dir}: {len(self.data)} training frames, fewer than one batch of {train_cfg.batch_size}")
        if train_cfg.batch_size % self.acc.num_processes:
            raise ValueError(f"batch size {train_cfg.batch_size} must divide among {self.acc.num_processes} processes")
        self.split_dir = Path(split_dir)
        self.step = 0
        # each process its own noise stream; process 0's is the single-process one
        self.noise = torch.Generator(device=self.device).manual_seed(train_cfg.seed + 1 + 1000 * self.acc.process_index)
        self.losses: list[float] = []
        self._validation: tuple[str, list[dict]] | None = None

    # -- data order: a pure function of (seed, step) ---------------------------------
    def batch_indices(self, step: int) -> np.ndarray:
        b = self.cfg.batch_size
        per_epoch = len(self.data) // b  # drop the last partial batch
        epoch, i = divmod(step, per_epoch)
        order = np.random.default_rng([self.cfg.seed, epoch]).permutation(len(self.data))
        return order[i * b:(i + 1) * b]

    def _batch(self, step: int) -> dict:
        mine = self.batch_indices(step)[self.acc.process_index::self.acc.num_processes]
        items = [self.data[int(i)] for i in mine]
        batch = {k: torch.stack([it[k] for it in items]) for k in ("condition", "wrench", "tactile")}
        return to_model_inputs(batch, self.device)

    # -- the loop ------------------------------------------------------------------------
    def train(self, until: int | None = None) -> list[float]:
        until = self.cfg.steps if until is None else until
        t0, done = time.perf_counter(), 0
        while self.step < until:
            batch = self._batch(self.step)
            with self.acc.autocast():
                loss = self.diffusion.loss(self.net, batch["tactile"], batch["condition"], batch["wrench"],
                                           generator=self.noise)
            self.opt.zero_grad(set_to_none=True)
            self.acc.backward(loss)
            self.opt.step()
            with torch.no_grad():
                # warm-up: early on the EMA follows the weights closely, so a short run's EMA
                # holds no trace of the random initial weights
                decay = min(self.cfg.ema_decay, (1 + self.step) / (10 + self.step))
                for e, p in zip(self.ema.parameters(), self.acc.unwrap_model(self.net).parameters()):
                    e.lerp_(p.float(), 1.0 - decay)
            self.step += 1
            done += 1
            self.losses.append(float(self.acc.reduce(loss.detach().float(), "mean")))
            if self.step % 50 == 0 or self.step == until:
                rate = done * self.cfg.batch_size / (time.perf_counter() - t0)
                self.log(f"step {self.step}/{until}  loss {np.mean(self.losses[-50:]):.4f}  {rate:.1f} images/s")
            if self.cfg.sample_every and self.step % self.cfg.sample_every == 0:
                self.sample_validation()
            if self.step % self.cfg.checkpoint_every == 0:
                self.save()
        return self.losses

    # -- validation samples ------------------------------------------------------------
    def sample_validation(self) -> Path | None:
        """samples/step-NNNNNN.png from the EMA weights: object at pose, real, generated, for a
        fixed set of held-out frames (the val part, else test). Touches no training state."""
        if not self.main:
            return None
        from dataset.torch_dataset import uint8_tensor_to_image
        from model.figures import samples_figure
        from model.inference import generate_items

        part, items = self._validation_items()
        if not items:
            return None
        made = generate_items(self.ema, self.diffusion, items, self.device, steps=self.cfg.sample_steps,
                              sampler="ddim", seed=self.cfg.seed)
        path = self.out / "samples" / f"step-{self.step:06d}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        samples_figure({"object at pose": [uint8_tensor_to_image(it["condition"]) for it in items],
                        "real": [uint8_tensor_to_image(it["tactile"]) for it in items],
                        f"step {self.step}": list(made)}, path)
        self.log(f"validation samples ({part}): {path}")
        return path

    def _validation_items(self) -> tuple[str, list[dict]]:
        """The held-out frames every validation PNG shows: read once."""
        if self._validation is None:
            from dataset.split import load_split
            from dataset.torch_dataset import spread

            _, parts = load_split(self.split_dir)
            part = "val" if "val" in parts else "test"
            data = TactileDataset(self.split_dir, part, size=self.model_cfg.image_size)
            self._validation = part, [data[int(i)] for i in spread(len(data), self.cfg.samples)]
        return self._validation

    # -- checkpoints -------------------------------------------------------------------
    def save(self) -> Path:
        ck = C.folder(self.out)
        self.acc.wait_for_everyone()
        if not self.main:
            return ck
        ck.mkdir(parents=True, exist_ok=True)
        C.write_tensors(ck, C.MODEL, self.acc.unwrap_model(self.net).state_dict())
        C.write_tensors(ck, C.EMA, self.ema.state_dict())
        opt = self.opt.state_dict()
        tensors = {f"{pid}.{key}": v for pid, st in opt["state"].items() for key, v in st.items()
                   if isinstance(v, torch.Tensor)}
        tensors["noise_generator_state"] = self.noise.get_state()
        C.write_tensors(ck, C.OPTIMIZER, tensors)
        meta = {"step": self.step, "model": dataclasses.asdict(self.model_cfg), "train": dataclasses.asdict(self.cfg),
                "param_groups": opt["param_groups"], "losses": self.losses,
                # what inference needs to condition like training did
                "wrench_mean": self.data.manifest["wrench_mean"], "wrench_std": self.data.manifest["wrench_std"],
                "mm_per_px": self.data.mm_per_px[0],
                # the frame width that mm_per_px belongs to: an object image spans frame_px × mm_per_px mm
                "frame_px": int(self.data.manifest["runs"][0]["frame_shape"][1])}
        C.write_state(ck, meta)  # last: a checkpoint with state.json is a complete one
        return ck

    def resume(self) -> None:
        ck = C.folder(self.out)
        meta = C.read_state(ck, hint=" to resume")
        saved = C.model_config(meta, ck / C.STATE)
        if saved != self.model_cfg:
            mine, theirs = dataclasses.asdict(self.model_cfg), dataclasses.asdict(saved)
            diff = {k: (theirs.get(k), v) for k, v in mine.items() if theirs.get(k) != v}
            raise CheckpointError(f"{ck}: trained with a different model config (checkpoint vs now: {diff})")
        C.load_weights(self.acc.unwrap_model(self.net), ck, C.MODEL, self.device)
        C.load_weights(self.ema, ck, C.EMA, self.device)
        tensors = C.read_tensors(ck, C.OPTIMIZER)
        noise_state = tensors.pop("noise_generator_state", None)
        if noise_state is None:
            raise CheckpointError(f"{ck / C.OPTIMIZER}: no noise_generator_state (an incomplete checkpoint)")
        if self.acc.process_index == 0:  # the others restart their streams (one state is saved)
            self.noise.set_state(noise_state)
        state: dict = {}
        for name, v in tensors.items():
            pid, _, key = name.partition(".")
            if not pid.isdigit() or not key:
                raise CheckpointError(f"{ck / C.OPTIMIZER}: unexpected tensor {name!r}")
            state.setdefault(int(pid), {})[key] = v.to(self.device) if key != "step" else v
        try:
            self.opt.load_state_dict({"state": state, "param_groups": meta["param_groups"]})
            self.losses = [float(x) for x in meta["losses"]]
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointError(f"{ck}: optimizer state does not fit this model ({exc})") from None
        self.step = meta["step"]


def _precision(choice: str, device: str | None) -> str:
    """accelerate's mixed_precision for a TrainConfig choice: none on CPU."""
    if choice not in ("auto", "no", "fp16", "bf16"):
        raise ValueError(f"mixed_precision must be auto, no, fp16 or bf16, got {choice!r}")
    if device == "cpu" or not torch.cuda.is_available():
        return "no"
    if choice == "auto":
        return "bf16" if torch.cuda.is_bf16_supported() else "fp16"
    return choice
