"""The trainer's callbacks: progress lines, validation images, checkpoints.

Each acts on the main process only (the others return at once), except that checkpoint
saves wait for every process and every process reads a checkpoint to resume.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Callable

import numpy as np

from common.eta import Eta
from model.denoiser import checkpoint as C
from model.denoiser.checkpoint import CheckpointError
from model.denoiser.config import ModelConfig
from model.training.trainer import Callback, Trainer


class Progress(Callback):
    """``step N/UNTIL  loss L  R images/s  ELAPSED, about LEFT left`` every ``every`` steps and at
    the last: the mean loss over the last ``every`` steps; the rate and the time left from this
    train() call's steps so far (``clock``: seconds, monotonic; injected in tests)."""

    def __init__(self, log: Callable[[str], None], every: int = 50, clock: Callable[[], float] = time.perf_counter):
        self.log, self.every = log, every
        self.eta = Eta(0, clock)

    def on_train_start(self, trainer: Trainer) -> None:
        self.eta = Eta(trainer.until, self.eta.clock, first=trainer.step)

    def on_step_end(self, trainer: Trainer) -> None:
        if trainer.is_main and (trainer.step % self.every == 0 or trainer.step == trainer.until):
            elapsed = self.eta.elapsed()
            images = (trainer.step - self.eta.first) * trainer.config.batch_size
            rate = f"{images / elapsed:.1f}" if elapsed > 0 else "?"
            loss = np.mean(trainer.losses[-self.every :])
            self.log(
                f"step {trainer.step}/{trainer.until}  loss {loss:.4f}  {rate} images/s  {self.eta.line(trainer.step)}"
            )


class ValidationSamples(Callback):
    """``OUT/samples/step-NNNNNN.png`` every ``every`` steps from the EMA weights: object at pose,
    real, generated, for ``count`` held-out frames (the split's val part, else test), read once.
    Touches no training state: its noise comes from its own generator."""

    def __init__(
        self,
        split_dir: str | Path,
        out_dir: str | Path,
        size: int,
        *,
        every: int,
        count: int = 4,
        steps: int = 25,
        seed: int = 0,
        log: Callable[[str], None] = print,
        physics=None,
    ):
        """``physics``: a physics model's PhysicsSpec (model/conditioning/physics_condition.py), which renders its
        channels."""
        self.split_dir, self.out, self.size = Path(split_dir), Path(out_dir), size
        self.every, self.count, self.steps, self.seed, self.log = every, count, steps, seed, log
        self.physics = physics
        self._items: tuple[str, list[dict]] | None = None

    def on_step_end(self, trainer: Trainer) -> None:
        if self.every and trainer.step % self.every == 0:
            self.write(trainer)

    def write(self, trainer: Trainer) -> Path | None:
        if not trainer.is_main:
            return None
        from dataset.torch_dataset import uint8_tensor_to_image
        from model.denoiser.precision import autocast_dtype
        from model.evaluation.figures import samples_figure
        from model.generation.inference import generate_items

        part, items = self.items()
        if not items:
            return None
        made = generate_items(
            trainer.ema,
            trainer.diffusion,
            items,
            trainer.device,
            steps=self.steps,
            sampler="ddim",
            seed=self.seed,
            physics=self.physics,
            autocast=autocast_dtype(trainer.acc.mixed_precision),  # the arithmetic the network trains in
        )
        path = self.out / "samples" / f"step-{trainer.step:06d}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        samples_figure(
            {
                "object at pose": [uint8_tensor_to_image(it["condition"]) for it in items],
                "real": [uint8_tensor_to_image(it["tactile"]) for it in items],
                f"step {trainer.step}": list(made),
            },
            path,
        )
        self.log(f"validation samples ({part}): {path}")
        return path

    def items(self) -> tuple[str, list[dict]]:
        if self._items is None:
            from dataset.split import load_split
            from dataset.torch_dataset import TactileDataset, spread

            _, parts = load_split(self.split_dir)
            part = "val" if "val" in parts else "test"
            data = TactileDataset(self.split_dir, part, size=self.size)
            self._items = part, [data[int(i)] for i in spread(len(data), self.count)]
        return self._items


class Checkpoints(Callback):
    """``OUT/checkpoint/`` (model/denoiser/checkpoint.py) every ``every`` steps and on ``trainer.save()``;
    ``trainer.resume()`` restores it after checking it was written for ``model_cfg``. ``meta``:
    what inference needs besides the weights (the model config, the conditioning statistics)."""

    def __init__(self, out_dir: str | Path, model_cfg: ModelConfig, meta: dict, *, every: int):
        self.folder, self.model_cfg, self.meta, self.every = C.folder(out_dir), model_cfg, meta, every

    def on_step_end(self, trainer: Trainer) -> None:
        if trainer.step % self.every == 0:
            self.on_save(trainer)

    def on_save(self, trainer: Trainer) -> Path:
        trainer.acc.wait_for_everyone()
        if trainer.is_main:
            meta = {
                **self.meta,
                "model": dataclasses.asdict(self.model_cfg),
                "train": dataclasses.asdict(trainer.config),
            }
            C.write_training_state(self.folder, trainer.state(), meta)
        return self.folder

    def on_resume(self, trainer: Trainer) -> bool:
        ck = self.folder
        meta = C.read_state(ck, hint=" to resume")
        saved = C.model_config(meta, ck / C.STATE)
        if saved != self.model_cfg:
            mine, theirs = dataclasses.asdict(self.model_cfg), dataclasses.asdict(saved)
            diff = {k: (theirs.get(k), v) for k, v in mine.items() if theirs.get(k) != v}
            raise CheckpointError(f"{ck}: trained with a different model config (checkpoint vs now: {diff})")
        state = C.read_training_state(ck, meta)
        try:
            trainer.load_state(state)
        except RuntimeError as exc:
            raise CheckpointError(f"{ck}: weights do not fit this model: {_first_line(exc)}") from None
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointError(f"{ck}: optimizer state does not fit this model ({_first_line(exc)})") from None
        return True


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
