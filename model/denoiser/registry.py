"""Which network denoises: ``ModelConfig.network`` names a row of NETWORKS.

Swapping the U-Net touches three files:

1. ``model/denoiser/<name>.py``: an ``nn.Module`` built from a ``ModelConfig`` whose
   ``forward(noisy (B, 3, S, S), timesteps (B,), condition (B, C, S, S), wrench (B, 6))``
   returns the ``ModelConfig.prediction`` target, (B, 3, S, S); C is
   ``ModelConfig.condition_channels`` (3: the object image; 6: then the physics render). ``model.denoiser.network``'s
   ``check_inputs`` and ``wrench_plane`` are there to share.
2. This file: one NETWORKS row, ``"name": TheModule``.
3. ``model/denoiser/config.py``: the hyper-parameters it needs, each with its reason (only if
   it needs new ones); then ``network = "name"`` under ``[model]`` in a model TOML.

Training (model/training/build.py), checkpoints, ``generate``, ``evaluate`` and the benches build
the network through ``build_network`` and take it from there.
"""

from __future__ import annotations

from torch import nn

from model.denoiser.config import ModelConfig
from model.denoiser.network import ContactDenoiser

NETWORKS: dict[str, type[nn.Module]] = {
    "unet2d": ContactDenoiser,  # diffusers' UNet2DModel, the paper's (Palette's) architecture
}


def build_network(cfg: ModelConfig) -> nn.Module:
    """The network ``cfg.network`` names, freshly initialised (from torch's global RNG)."""
    if cfg.network not in NETWORKS:
        raise ValueError(f"network must be one of {', '.join(NETWORKS)}, got {cfg.network!r}")
    return NETWORKS[cfg.network](cfg)
