"""A training run's pieces, built in one place from the two configs: the network (through the
registry), the diffusion, the training data, the callbacks, and the Trainer that joins them."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np
import torch

from dataset.torch_dataset import TactileDataset
from model.conditioning.force_augment import ForceAugmented, levels_cache
from model.denoiser.config import ModelConfig
from model.denoiser.diffusion import Diffusion
from model.denoiser.registry import build_network
from model.training.callbacks import Checkpoints, Progress, ValidationSamples
from model.training.trainer import Callback, TrainConfig, Trainer


def build(
    model_cfg: ModelConfig,
    train_cfg: TrainConfig,
    split_dir: str | Path,
    out_dir: str | Path,
    *,
    device: str | None = None,
    log: Callable[[str], None] = print,
    profile=None,
    override_profile: bool = False,
) -> Trainer:
    """A Trainer on the split's train part writing to ``out_dir`` (checkpoint/, samples/), logging
    through ``log`` on the main process. Raises ValueError for a split with less than one batch.
    ``profile``: the SensorProfile of physics conditioning for runs that record none (``--profile``);
    a run that records another is refused unless ``override_profile``; the profile of each run is logged."""
    physics = spec = None
    if model_cfg.uses_physics:  # the train part's physics renders, made once per size (minutes) and cached
        from model.conditioning.force_render import force_physics_cache
        from model.conditioning.physics_condition import physics_cache, split_spec

        # one line for an object the simulator lacks, a run without a profile, a profile --profile contradicts
        spec = split_spec(split_dir, profile, override=override_profile, log=log)
        cache = force_physics_cache if model_cfg.force_depth else physics_cache  # at Fz's depth, or the pose's z
        physics = cache(split_dir, "train", model_cfg.image_size, spec, log=log)
    data: TactileDataset | ForceAugmented = TactileDataset(
        split_dir, "train", size=model_cfg.image_size, physics=physics
    )
    if model_cfg.force_augment:  # each frame again at four other loads (model/conditioning/force_augment.py)
        span = model_cfg.force_augment
        levels = levels_cache(split_dir, "train", model_cfg.image_size, span, spec, log=log)
        data = ForceAugmented(data, np.load(levels, mmap_mode="r"), span)
    if len(data) < train_cfg.batch_size:
        raise ValueError(f"{split_dir}: {len(data)} training items, fewer than one batch of {train_cfg.batch_size}")
    torch.manual_seed(train_cfg.seed)  # initial weights: the same in every process
    net = build_network(model_cfg)
    meta = {  # what inference needs to condition like training did
        "wrench_mean": data.manifest["wrench_mean"],
        "wrench_std": data.manifest["wrench_std"],
        "mm_per_px": data.mm_per_px[0],
        # the frame width that mm_per_px belongs to: an object image spans frame_px × mm_per_px mm
        "frame_px": int(data.manifest["runs"][0]["frame_shape"][1]),
    }
    if spec is not None:
        meta["physics"] = spec.to_meta()  # what renders the physics channels at inference
    callbacks: list[Callback] = [Progress(log)]
    if train_cfg.sample_every:
        callbacks.append(
            ValidationSamples(
                split_dir,
                out_dir,
                model_cfg.image_size,
                every=train_cfg.sample_every,
                count=train_cfg.samples,
                steps=train_cfg.sample_steps,
                seed=train_cfg.seed,
                log=log,
                physics=spec,
            )
        )
    callbacks.append(Checkpoints(out_dir, model_cfg, meta, every=train_cfg.checkpoint_every))
    return Trainer(train_cfg, net, Diffusion(model_cfg), data, callbacks, device=device)
