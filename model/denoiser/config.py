"""The model's configuration: one frozen dataclass, a reason beside each default."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

# The condition's components, joined by "+" in any order (validated in ModelConfig):
# plane: the paper's H(F), a wrench plane beside the object image; embedding: a learned wrench
# embedding added to the time embedding; physics: the simulator's render of the frame at its
# measured pose (model/conditioning/physics_condition.py), three more image channels.
COMPONENTS = ("plane", "embedding", "physics")
CONDITIONINGS = (  # the named choices `train --conditioning` and the benches offer
    "plane",
    "embedding",
    "plane+embedding",
    "physics",
    "physics+embedding",
    "physics+plane",
    "physics+plane+embedding",
)
# `train`'s default per sensor kind when neither --conditioning nor a model TOML names one:
# measured on two held-out objects, 32 px (docs/results/conditioning/): physics beat the paper's
# plane 45 vs 161 MSE on rgb; physics+plane+embedding was best on rgb_markers (229 vs 342).
# white_markers was not measured: it takes the other marker sensor's. The presets keep
# "plane+embedding", and so does `train` where the simulator cannot render the split's objects.
DEFAULT_CONDITIONING = {
    "rgb": "physics",
    "rgb_markers": "physics+plane+embedding",
    "white_markers": "physics+plane+embedding",
}
# ...and the target that goes with that default: for the marker sensors the residual on the
# physics render, measured against the frame target at 128 px on two held-out objects, 400
# steps each (docs/results/markers128-physics/): MSE 42 vs 70 (rgb_markers), 74 vs 131
# (white_markers), SSIM and marker error better as well. rgb was not measured: the frame.
DEFAULT_TARGET = {"rgb_markers": "physics_residual", "white_markers": "physics_residual"}
PREDICTIONS = ("epsilon", "v_prediction", "sample")
# What the diffusion denoises: the tactile frame itself (the paper), or its difference from the
# physics channels' render (``physics_residual``: the model learns what the calibrated simulator
# gets wrong, and a sample is the render plus that; needs physics conditioning).
TARGETS = ("frame", "physics_residual")
# Where the physics channels are rendered: at the frame's measured pose z ("pose"), or at the depth
# where the simulator's contact gives the frame's measured Fz ("force", model/conditioning/force_render.py): then
# the wrench shapes the picture the network is given, in training, in a force sweep and in
# `generate` alike, and a force past the training range is still a physical contact.
PHYSICS_DEPTHS = ("pose", "force")


@dataclass(frozen=True)
class ModelConfig:
    network: str = "unet2d"  # a row of model/denoiser/registry.py's NETWORKS: the paper's U-Net
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
    target: str = "frame"  # one of TARGETS; physics_residual measured in docs/results/markers128-physics
    physics_depth: str = "pose"  # one of PHYSICS_DEPTHS: the physics render at the pose's z, or at Fz's depth
    # physics_residual: the residual (frame − render)/2 is multiplied by this before it is noised. A real
    # sensor's residual is a few grey levels (std ~0.01 of the range): at gain 1 the noise drowns it at
    # almost every step and the network learns little of it. 8 on the real GelSight presses: MSE 3.42 vs
    # 10.22 (docs/results/real-gelsight/gain). 1 stays the default: the marker sensors' residual default
    # was measured at 1 and gain 8 is not measured there.
    residual_gain: float = 1.0
    # force augmentation (needs physics_depth force): each training frame is also shown at Fz × (1 ± s,
    # 1 ± s/2), with the render at that load and its contact grown or shrunk as the render's
    # (model/conditioning/force_augment.py): an assumption the real frames cannot check. 0: off.
    force_augment: float = 0.0

    def __post_init__(self):
        self._check_types()
        parts = str(self.conditioning).split("+")
        if (
            not isinstance(self.conditioning, str)
            or any(p not in COMPONENTS for p in parts)
            or len(set(parts)) < len(parts)
        ):
            raise ValueError(
                f"conditioning must be one or more of {', '.join(COMPONENTS)} joined by '+' "
                f"(e.g. {', '.join(CONDITIONINGS[2:5])}), got {self.conditioning!r}"
            )
        if self.prediction not in PREDICTIONS:
            raise ValueError(f"prediction must be one of {', '.join(PREDICTIONS)}, got {self.prediction!r}")
        if self.target not in TARGETS:
            raise ValueError(f"target must be one of {', '.join(TARGETS)}, got {self.target!r}")
        if self.physics_depth not in PHYSICS_DEPTHS:
            raise ValueError(f"physics_depth must be one of {', '.join(PHYSICS_DEPTHS)}, got {self.physics_depth!r}")
        if self.physics_depth == "force" and "physics" not in parts:
            raise ValueError(
                f"physics_depth force renders the physics channels at the depth Fz implies: it needs physics "
                f"conditioning; conditioning is {self.conditioning!r}"
            )
        if self.target == "physics_residual" and "physics" not in parts:
            raise ValueError(
                f"target physics_residual needs physics conditioning (the render it is a residual of); "
                f"conditioning is {self.conditioning!r}"
            )
        if not 0 < self.residual_gain <= 1000:
            raise ValueError(f"residual_gain must be a number in (0, 1000], got {self.residual_gain!r}")
        if self.residual_gain != 1.0 and self.target != "physics_residual":
            raise ValueError(
                f"residual_gain scales the physics residual: it needs target physics_residual, got {self.target!r}"
            )
        if not 0.0 <= self.force_augment <= 0.9:
            raise ValueError(f"force_augment must be a fraction of Fz in [0, 0.9], got {self.force_augment!r}")
        if self.force_augment and not self.force_depth:
            raise ValueError(
                "force_augment re-renders each frame at other forces: it needs physics_depth force, "
                f"got physics_depth {self.physics_depth!r}"
            )
        levels = len(self.block_out_channels)
        if self.image_size % (2 ** (levels - 1)):
            raise ValueError(
                f"image_size {self.image_size} must be divisible by {2 ** (levels - 1)} ({levels} resolution levels)"
            )
        if not 0.0 <= self.cond_dropout < 1.0:
            raise ValueError(f"cond_dropout must be in [0, 1), got {self.cond_dropout}")

    def _check_types(self) -> None:
        """Every field of its default's type (a checkpoint's or a file's "many" is named, not
        formatted into a Python error): ValueError naming the field, the value and the type."""
        for f in fields(self):
            value, default = getattr(self, f.name), f.default
            if isinstance(default, bool):
                ok, what = isinstance(value, bool), "true or false"
            elif isinstance(default, int):
                ok, what = isinstance(value, int) and not isinstance(value, bool) and value > 0, "a whole number > 0"
            elif isinstance(default, float):
                ok = isinstance(value, (int, float)) and not isinstance(value, bool) and value == value
                what = "a number"
            elif isinstance(default, tuple):
                ok = (
                    isinstance(value, tuple)
                    and bool(value)
                    and all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in value)
                )
                what = "a list of whole numbers > 0"
            else:
                ok, what = isinstance(value, str), "text"
            if not ok:
                raise ValueError(f"{f.name} must be {what}, got {value!r}")

    @property
    def uses_plane(self) -> bool:
        return "plane" in self.conditioning.split("+")

    @property
    def uses_embedding(self) -> bool:
        return "embedding" in self.conditioning.split("+")

    @property
    def uses_physics(self) -> bool:
        return "physics" in self.conditioning.split("+")

    @property
    def force_depth(self) -> bool:
        """The physics channels are rendered at the depth the frame's Fz implies (``physics_depth``)."""
        return self.physics_depth == "force"

    @property
    def residual(self) -> bool:
        """The diffusion denoises the frame's difference from the physics render (``target``)."""
        return self.target == "physics_residual"

    @property
    def condition_channels(self) -> int:
        """Image channels of the condition: the object image (RGB), then the physics render (RGB)."""
        return 6 if self.uses_physics else 3


def default_conditioning(sensor_kind: str) -> str:
    """The measured best conditioning for a sensor kind (plane+embedding for a kind not measured)."""
    return DEFAULT_CONDITIONING.get(sensor_kind, "plane+embedding")


def default_target(sensor_kind: str, conditioning: str) -> str:
    """The measured best target for a sensor kind with that conditioning (frame without physics)."""
    return DEFAULT_TARGET.get(sensor_kind, "frame") if "physics" in conditioning.split("+") else "frame"


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
