"""The ``unet2d`` network: a diffusers U-Net over [noisy tactile, object image, H(F)] (Palette's
concatenated condition), and the input checks and wrench plane any network may share.

Shapes: noisy y_t (B, 3, S, S), condition (B, 3, S, S): the object image, or (B, 6, S, S):
the object image then the physics render (``physics`` conditioning, model/conditioning/physics_condition.py),
wrench (B, 6) normalised, timesteps (B,). The paper's H(F) expands the wrench into a (B, 1, S, S) plane (here:
six vertical stripes, one per component); the learned embedding maps it to the
U-Net's time-embedding width and is added there, as the timestep is. The output is the
``ModelConfig.prediction`` target (y₀ by default, or ε, or v); the diffusion maths
(model/denoiser/diffusion.py) turns it into what the samplers need. Other networks: model/denoiser/registry.py.
"""

from __future__ import annotations

import torch
from torch import nn

from model.denoiser.config import ModelConfig


def wrench_plane(wrench: torch.Tensor, size: int) -> torch.Tensor:
    """(B, 6) → (B, 1, size, size): stripe k of the plane holds component k."""
    stripes = torch.repeat_interleave(wrench, repeats=-(-size // 6), dim=1)[:, :size]  # (B, size)
    return stripes[:, None, None, :].expand(-1, 1, size, size)


def check_inputs(noisy: torch.Tensor, condition: torch.Tensor, wrench: torch.Tensor, channels: int = 3) -> None:
    """Clear errors for inputs no denoiser can take (ValueError naming the shapes). ``channels``:
    the condition's (ModelConfig.condition_channels: 3, or 6 with the physics render)."""
    expected = (noisy.shape[0], channels, *noisy.shape[2:])
    if tuple(condition.shape) != expected:
        raise ValueError(
            f"condition image {tuple(condition.shape)} must match the tactile image {tuple(noisy.shape)} in batch "
            f"and size, with {channels} channels ({'object image + physics render' if channels == 6 else 'RGB'})"
        )
    check_wrench(wrench, noisy.shape[0])


def check_wrench(wrench: torch.Tensor, batch: int, limit: float = 1e3) -> None:
    """A clear error for a wrench that cannot be a normalised six-axis reading."""
    if wrench.ndim != 2 or wrench.shape != (batch, 6):
        raise ValueError(f"wrench must be (batch, 6) = ({batch}, 6): Fx Fy Fz Mx My Mz, got {tuple(wrench.shape)}")
    if not torch.isfinite(wrench).all():
        raise ValueError("wrench has NaN or inf")
    if wrench.abs().max() > limit:
        raise ValueError(
            f"wrench component {wrench.abs().max().item():.3g} is absurd for a normalised wrench "
            f"(|value| > {limit:g}): normalise with the split's statistics"
        )


class ContactDenoiser(nn.Module):
    def __init__(self, cfg: ModelConfig):
        super().__init__()
        from diffusers import UNet2DModel

        self.cfg = cfg
        levels = len(cfg.block_out_channels)
        down = ["DownBlock2D"] * levels
        up = ["UpBlock2D"] * levels
        if cfg.attention:
            down[-1], up[0] = "AttnDownBlock2D", "AttnUpBlock2D"
        embed_dim = cfg.block_out_channels[0] * 4  # UNet2DModel's time-embedding width
        self.unet = UNet2DModel(
            sample_size=cfg.image_size,
            in_channels=3 + cfg.condition_channels + (1 if cfg.uses_plane else 0),
            out_channels=3,
            block_out_channels=cfg.block_out_channels,
            layers_per_block=cfg.layers_per_block,
            down_block_types=tuple(down),
            up_block_types=tuple(up),
            class_embed_type="identity" if cfg.uses_embedding else None,
            norm_num_groups=min(32, cfg.block_out_channels[0]),
        )
        self.wrench_embed = (
            nn.Sequential(nn.Linear(6, embed_dim), nn.SiLU(), nn.Linear(embed_dim, embed_dim))
            if cfg.uses_embedding
            else None
        )

    def forward(
        self, noisy: torch.Tensor, timesteps: torch.Tensor, condition: torch.Tensor, wrench: torch.Tensor
    ) -> torch.Tensor:
        """The prediction target (ModelConfig.prediction: y₀, ε or v), (B, 3, S, S)."""
        s = noisy.shape[-1]
        check_inputs(noisy, condition, wrench, self.cfg.condition_channels)
        parts = [noisy, condition]  # (B, 3, S, S), (B, 3 or 6, S, S)
        if self.cfg.uses_plane:
            parts.append(wrench_plane(wrench, s))  # (B, 1, S, S)
        x = torch.cat(parts, dim=1)  # (B, 6 to 10, S, S)
        labels = self.wrench_embed(wrench) if self.wrench_embed is not None else None  # (B, 4·C0)
        # diffusers types ModelMixin without nn.Module.__call__; the call is the module's forward with hooks
        return self.unet(x, timesteps, class_labels=labels).sample  # type: ignore[operator]
