"""The model's configuration: one frozen dataclass, a reason beside each default."""

from __future__ import annotations

from dataclasses import dataclass, replace

CONDITIONINGS = ("plane", "embedding", "plane+embedding")
PREDICTIONS = ("epsilon", "v_prediction", "sample")


@dataclass(frozen=True)
class ModelConfig:
    network: str = "unet2d"  # a row of model/registry.py's NETWORKS: the paper's U-Net
    image_size: int = 64  # tactile and condition images are square; 256 in the paper
    block_out_channels: tuple[int, ...] = (32, 64, 64)  # U-Net width per resolution level
    layers_per_block: int = 1  # resnet blocks per level (2 in Palette/SR3-style models)
    attention: bool = False  # self-attention at the lowest resolution (costly on CPU)
    conditioning: str = "plane+embedding"  # the paper's wrench plane H(F), a learned embedding, or both
    train_timesteps: int = 1000  # DDPM's usual T
    beta_schedule: str = "squaredcos_cap_v2"  # cosine: better at small image sizes than linear
    cond_dropout: float = 0.1  # drop the condition this often in training: classifier-free guidance
    # what the network predicts: y₀ itself ("sample"), ε (the paper's loss) or v = √ᾱ·ε − √(1−ᾱ)·y₀.
    # Measured (docs/model.md): after 1000 CPU steps y₀ gives MSE 5.2, v 63, ε 2086 (noisy frames).
    prediction: str = "sample"

    def __post_init__(self):
        if self.conditioning not in CONDITIONINGS:
            raise ValueError(f"conditioning must be one of {', '.join(CONDITIONINGS)}, got {self.conditioning!r}")
        if self.prediction not in PREDICTIONS:
            raise ValueError(f"prediction must be one of {', '.join(PREDICTIONS)}, got {self.prediction!r}")
        levels = len(self.block_out_channels)
        if self.image_size % (2 ** (levels - 1)):
            raise ValueError(
                f"image_size {self.image_size} must be divisible by {2 ** (levels - 1)} ({levels} resolution levels)"
            )
        if not 0.0 <= self.cond_dropout < 1.0:
            raise ValueError(f"cond_dropout must be in [0, 1), got {self.cond_dropout}")

    @property
    def uses_plane(self) -> bool:
        return "plane" in self.conditioning

    @property
    def uses_embedding(self) -> bool:
        return "embedding" in self.conditioning


PRESETS = {
    # CPU: tests and the demo.
    "tiny": ModelConfig(image_size=32, block_out_channels=(32, 64, 64), layers_per_block=1),
    # GPU: the paper's resolution.
    "paper": ModelConfig(image_size=256, block_out_channels=(64, 128, 256, 256), layers_per_block=2, attention=True),
}


# Training defaults that belong to a preset (the rest are TrainConfig's).
PRESET_TRAINING = {
    "tiny": {"lr": 1e-3},  # a small net on CPU: converges fastest here (docs/model.md)
    "paper": {"lr": 2e-4},  # Palette/SR3's rate for a 256 px U-Net
}


def preset(name: str, **overrides) -> ModelConfig:
    if name not in PRESETS:
        raise KeyError(f"unknown preset {name!r}; presets: {', '.join(PRESETS)}")
    return replace(PRESETS[name], **overrides)
