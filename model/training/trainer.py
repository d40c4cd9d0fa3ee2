"""Training: a loop that knows the network only through the diffusion loss (minGPT's trainer).

``Trainer(config, net, diffusion, data, callbacks)`` is handed a built network, the
diffusion (the loop calls only its ``batch_loss(net, batch, generator)``), a Dataset of
dict items and callbacks; ``model/training/build.py`` builds them all from the configs. Progress
lines, validation images and checkpoints are callbacks (model/training/callbacks.py) on the
events ``on_train_start``, ``on_step_end``, ``on_train_end``, ``on_save`` and ``on_resume``.

Items are read from the Dataset once and kept (up to ``ITEM_CACHE_BYTES``): after the first
epoch a step reads no file and resizes no image. So a Dataset's item must be a function of its
index alone (TactileDataset's is: no random augmentation).

Exact resume: the data order is a function of (seed, step) alone, and ``state()`` holds
the weights, their EMA, the optimizer and the noise generator, so a run resumed from it
takes the same steps with the same losses as an uninterrupted one.

Several GPUs or nodes: ``accelerate launch -m cli.model_app ...`` (or ``accelerate launch
$(which train) ...``) runs this same loop in each process; each takes its share of the
step's batch (the global batch and its order are the single-process ones), the gradients
are averaged by accelerate, and callbacks act on the main process only (``is_main``). A process
reads from the Dataset only the items of its share (``read``: their indices): within an epoch the
processes' items are disjoint, so each reads its own shard of the data. On a machine without GPUs
``accelerate launch --multi_gpu --num_processes N ... --device cpu`` runs N CPU processes over gloo
(accelerate 1.15's ``--cpu`` alone starts one process unless given an MPI hostfile; docs/model.md).
Mixed precision (bf16, or fp16 with loss scaling) on CUDA.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from model.denoiser.precision import training_precision

ITEM_CACHE_BYTES = 1 << 30  # items kept in memory up to this many bytes of tensors; the rest are re-read


@dataclass(frozen=True)
class TrainConfig:
    steps: int = 2000  # optimisation steps in all
    batch_size: int = 16
    lr: float = 2e-4  # Adam, as Palette/SR3 (presets set their own: model/denoiser/config.py PRESET_TRAINING)
    ema_decay: float = 0.999  # sampling uses the EMA weights
    checkpoint_every: int = 500
    sample_every: int = 500  # validation samples saved as PNG this often (0: never)
    samples: int = 4  # validation frames in each PNG
    sample_steps: int = 25  # DDIM steps for the validation samples
    seed: int = 0  # data order and noise
    # auto (CUDA: bf16 where supported, else fp16; CPU: bf16 where native, else none) | no | fp16 | bf16
    mixed_precision: str = "auto"


class Callback:
    """Hooks the trainer calls; each gets the trainer. A subclass overrides what it needs;
    ``on_save`` returns where it saved, ``on_resume`` True when it restored the state."""

    def on_train_start(self, trainer: "Trainer") -> None: ...
    def on_step_end(self, trainer: "Trainer") -> None: ...
    def on_train_end(self, trainer: "Trainer") -> None: ...
    def on_save(self, trainer: "Trainer"): ...
    def on_resume(self, trainer: "Trainer"): ...


class Trainer:
    def __init__(
        self,
        config: TrainConfig,
        net: torch.nn.Module,
        diffusion,
        data,
        callbacks: Sequence[Callback] = (),
        *,
        device: str | None = None,
    ):
        from accelerate import Accelerator

        self.config = config
        self.acc = Accelerator(cpu=device == "cpu", mixed_precision=training_precision(config.mixed_precision, device))
        self.device = self.acc.device
        self.is_main = self.acc.is_main_process
        if config.batch_size % self.acc.num_processes:
            raise ValueError(f"batch size {config.batch_size} must divide among {self.acc.num_processes} processes")
        if len(data) < config.batch_size:
            raise ValueError(f"{len(data)} training items, fewer than one batch of {config.batch_size}")
        net = net.to(self.device)
        self.ema = copy.deepcopy(net).eval().requires_grad_(False)
        # foreach: one kernel per operation over all the parameters instead of a Python loop over 150
        # tensors (torch's default on CUDA, not on CPU); the same arithmetic, bit for bit (docs/benchmarks.md)
        self.net, self.opt = self.acc.prepare(net, torch.optim.Adam(net.parameters(), lr=config.lr, foreach=True))
        self.diffusion, self.data, self.callbacks = diffusion, data, list(callbacks)
        self._items: dict[int, dict] = {}
        self._item_bytes = 0
        self.read: set[int] = set()  # indices of the Dataset items this process has read
        self.step = 0
        self.until = config.steps  # the step this train() call stops at
        self.losses: list[float] = []
        # each process its own noise stream; process 0's is the single-process one
        self.noise = torch.Generator(device=self.device).manual_seed(config.seed + 1 + 1000 * self.acc.process_index)

    def _fire(self, event: str) -> list:
        return [getattr(cb, event)(self) for cb in self.callbacks]

    # -- data order: a pure function of (seed, step) ---------------------------------
    def batch_indices(self, step: int) -> np.ndarray:
        b = self.config.batch_size
        per_epoch = len(self.data) // b  # drop the last partial batch
        epoch, i = divmod(step, per_epoch)
        order = np.random.default_rng([self.config.seed, epoch]).permutation(len(self.data))
        return order[i * b : (i + 1) * b]

    def share(self, step: int, process: int | None = None) -> np.ndarray:
        """The indices of ``process``'s (default: this one's) share of the step's global batch."""
        rank = self.acc.process_index if process is None else process
        return self.batch_indices(step)[rank :: self.acc.num_processes]

    def _batch(self, step: int) -> dict:
        """This process's share of the step's batch: the items' tensors stacked, on the device."""
        mine = self.share(step)
        items = [self._item(int(i)) for i in mine]
        return {
            k: torch.stack([it[k] for it in items]).to(self.device, non_blocking=True)
            for k, v in items[0].items()
            if isinstance(v, torch.Tensor)
        }

    def _item(self, index: int) -> dict:
        """The Dataset's item, read once and kept while the cache holds under ITEM_CACHE_BYTES."""
        item = self._items.get(index)
        if item is None:
            item = self.data[index]
            self.read.add(index)
            size = sum(v.numel() * v.element_size() for v in item.values() if isinstance(v, torch.Tensor))
            if self._item_bytes + size <= ITEM_CACHE_BYTES:
                self._items[index] = item
                self._item_bytes += size
        return item

    # -- the loop ------------------------------------------------------------------------
    def train(self, until: int | None = None) -> list[float]:
        """Optimise up to step ``until`` (the config's steps by default); the losses of every step so far."""
        self.until = self.config.steps if until is None else until
        self._fire("on_train_start")
        while self.step < self.until:
            batch = self._batch(self.step)
            with self.acc.autocast():
                loss = self.diffusion.batch_loss(self.net, batch, generator=self.noise)
            self.opt.zero_grad(set_to_none=True)
            self.acc.backward(loss)
            self.opt.step()
            self._update_ema()
            self.step += 1
            self.losses.append(float(self.acc.reduce(loss.detach().float(), "mean")))
            self._fire("on_step_end")
        self._fire("on_train_end")
        return self.losses

    @torch.no_grad()
    def _update_ema(self) -> None:
        # warm-up: early on the EMA follows the weights closely, so a short run's EMA
        # holds no trace of the random initial weights
        decay = min(self.config.ema_decay, (1 + self.step) / (10 + self.step))
        ema: list[torch.Tensor] = list(self.ema.parameters())
        weights: list[torch.Tensor] = [p.float() for p in self.acc.unwrap_model(self.net).parameters()]
        torch._foreach_lerp_(ema, weights, 1.0 - decay)  # each e.lerp_(p, 1 − decay), in one call

    # -- state for exact resume ----------------------------------------------------------
    def state(self) -> dict:
        """Everything exact resume needs: step, losses, weights, EMA, optimizer, noise generator; a
        copy on the CPU (training on does not change it)."""
        return _cpu_copy(
            {
                "step": self.step,
                "losses": list(self.losses),
                "model": self.acc.unwrap_model(self.net).state_dict(),
                "ema": self.ema.state_dict(),
                "optimizer": self.opt.state_dict(),
                "noise": self.noise.get_state(),
            }
        )

    def load_state(self, state: dict) -> None:
        """Restore ``state()``'s output. Raises RuntimeError (weights) or KeyError, TypeError,
        ValueError (optimizer) when it does not fit this network."""
        self.acc.unwrap_model(self.net).load_state_dict(state["model"])
        self.ema.load_state_dict(state["ema"])
        self.opt.load_state_dict(state["optimizer"])
        if self.acc.process_index == 0:  # the others restart their streams (one state is saved)
            self.noise.set_state(state["noise"])
        self.step, self.losses = int(state["step"]), [float(x) for x in state["losses"]]

    def save(self):
        """Ask the callbacks to save (``on_save``): where the first one saved, else None."""
        return next((r for r in self._fire("on_save") if r is not None), None)

    def resume(self) -> None:
        """Ask the callbacks to restore a saved state (``on_resume``); ValueError when none can."""
        if not any(self._fire("on_resume")):
            raise ValueError("nothing to resume from: no callback restores a saved state")


def _cpu_copy(obj):
    """Tensors copied to the CPU, in nested dicts and lists (state dicts share the live tensors)."""
    if isinstance(obj, torch.Tensor):
        return obj.detach().to("cpu", copy=True)
    if isinstance(obj, dict):
        return {k: _cpu_copy(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(_cpu_copy(v) for v in obj)
    return obj
