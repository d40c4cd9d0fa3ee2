"""Diffusion maths apart from the network: the noise schedule, the training loss, the denoiser.

Forward process (Ho et al. 2020 eq. 4): y_t = √ᾱ_t·y₀ + √(1−ᾱ_t)·ε, cosine ᾱ (Nichol and
Dhariwal 2021) by default. The network f_θ(y_t, t, I, F) regresses ``ModelConfig.prediction``:
y₀ itself ("sample", the default, measured best in docs/model.md), ε (the paper's loss,
§III-B) or v = √ᾱ_t·ε − √(1−ᾱ_t)·y₀; the loss is E‖target − f_θ‖². The samplers
(model/denoiser/samplers.py) see none of that: they call ``denoiser(...)``, which turns whatever
the network predicts into the clean-image estimate ŷ₀.

Classifier-free guidance (Ho and Salimans 2022): training replaces the condition (object
image, wrench) by zeros with probability ``cond_dropout``; sampling evaluates the conditional
and unconditional halves in one batch and takes pred = uncond + w·(cond − uncond).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

from model.denoiser.config import ModelConfig
from model.denoiser.samplers import CLIPPED, SAMPLERS, SPACING, Denoise, spaced_timesteps


def alpha_bar_schedule(name: str, steps: int) -> torch.Tensor:
    """ᾱ_t for t = 0 … steps−1 (float32, computed in float64); diffusers' schedules of the same names."""
    if name == "squaredcos_cap_v2":  # Nichol and Dhariwal 2021 eq. 17, β capped at 0.999
        f = [math.cos((i / steps + 0.008) / 1.008 * math.pi / 2) ** 2 for i in range(steps + 1)]
        betas = torch.tensor([min(1 - f[i + 1] / f[i], 0.999) for i in range(steps)], dtype=torch.float64)
    elif name == "linear":  # Ho et al. 2020
        betas = torch.linspace(1e-4, 0.02, steps, dtype=torch.float64)
    elif name == "scaled_linear":  # latent diffusion's
        betas = torch.linspace(1e-4**0.5, 0.02**0.5, steps, dtype=torch.float64) ** 2
    else:
        raise ValueError(f"beta_schedule must be squaredcos_cap_v2, linear or scaled_linear, got {name!r}")
    return torch.cumprod(1.0 - betas, dim=0).float()


class Diffusion:
    def __init__(self, cfg: ModelConfig):
        self.cfg = cfg
        self.alpha_bar = alpha_bar_schedule(cfg.beta_schedule, cfg.train_timesteps)  # (T,)
        self._on: dict[torch.device, torch.Tensor] = {}

    def _alpha_bar(self, t: torch.Tensor) -> torch.Tensor:
        """ᾱ_t as (B, 1, 1, 1) on t's device (cached there: no host copy per step)."""
        if t.device not in self._on:
            self._on[t.device] = self.alpha_bar.to(t.device)
        return self._on[t.device][t].view(-1, 1, 1, 1)

    # -- training ------------------------------------------------------------------------
    def loss(
        self,
        net,
        tactile: torch.Tensor,
        condition: torch.Tensor,
        wrench: torch.Tensor,
        generator: torch.Generator | None = None,
    ) -> torch.Tensor:
        """Mean squared error of the network's target for a batch of clean tactile images in [−1, 1]."""
        b, dev = tactile.shape[0], tactile.device
        if self.cfg.residual:  # the difference from the physics render (the last three condition channels)
            tactile = to_residual(tactile, condition, self.cfg.residual_gain)
        t = torch.randint(0, self.cfg.train_timesteps, (b,), device=dev, generator=generator)
        noise = torch.randn(tactile.shape, device=dev, generator=generator)
        a = self._alpha_bar(t).to(tactile.dtype)
        noisy = a.sqrt() * tactile + (1 - a).sqrt() * noise
        if self.cfg.cond_dropout > 0:
            keep = (torch.rand((b,), device=dev, generator=generator) >= self.cfg.cond_dropout).float()
            condition = condition * keep[:, None, None, None]
            wrench = wrench * keep[:, None]
        if self.cfg.prediction == "epsilon":
            target = noise
        elif self.cfg.prediction == "v_prediction":
            target = a.sqrt() * noise - (1 - a).sqrt() * tactile
        else:
            target = tactile
        return F.mse_loss(net(noisy, t, condition, wrench), target)

    def batch_loss(self, net, batch: dict, generator: torch.Generator | None = None) -> torch.Tensor:
        """``loss`` for a collated Dataset batch on the training device: images uint8 0–255."""
        from dataset.torch_dataset import condition_of, scale_images

        # condition_of: the object image, then the physics render when the batch has one
        return self.loss(
            net, scale_images(batch["tactile"]), scale_images(condition_of(batch)), batch["wrench"], generator=generator
        )

    # -- sampling ------------------------------------------------------------------------
    def to_x0(self, out: torch.Tensor, x: torch.Tensor, t: int) -> torch.Tensor:
        """The clean-image estimate ŷ₀ from the network's output at step t (eq. 4 rearranged)."""
        a = float(self.alpha_bar[t])
        if self.cfg.prediction == "epsilon":
            return (x - math.sqrt(1 - a) * out) / math.sqrt(a)
        if self.cfg.prediction == "v_prediction":
            return math.sqrt(a) * x - math.sqrt(1 - a) * out
        return out

    def denoiser(
        self,
        net,
        condition: torch.Tensor,
        wrench: torch.Tensor,
        *,
        guidance: float = 1.0,
        autocast: torch.dtype | None = None,
    ) -> Denoise:
        """D(y_t, t) → ŷ₀ for a batch of conditions. With guidance w ≠ 1 each call is one forward
        pass over 2B: the conditional half, then the unconditional (zeros), combined as
        uncond + w·(cond − uncond) on the network's output (the same as on ŷ₀: the conversion is
        affine in the output). ``autocast``: the network runs under autocast to that dtype
        (model/denoiser/precision.py); its output, and all that follows, is fp32."""
        b = condition.shape[0]
        if guidance != 1.0:
            condition = torch.cat([condition, torch.zeros_like(condition)])  # (2B, 3, S, S)
            wrench = torch.cat([wrench, torch.zeros_like(wrench)])  # (2B, 6)

        def run(x: torch.Tensor, tt: torch.Tensor) -> torch.Tensor:
            if autocast is None:
                return net(x, tt, condition, wrench)
            with torch.autocast(x.device.type, dtype=autocast):
                return net(x, tt, condition, wrench).float()

        def denoise(x: torch.Tensor, t: int) -> torch.Tensor:
            if guidance == 1.0:
                out = run(x, torch.full((b,), t, device=x.device, dtype=torch.long))
            else:
                tt = torch.full((2 * b,), t, device=x.device, dtype=torch.long)
                cond, uncond = run(torch.cat([x, x]), tt).chunk(2)  # (B, 3, S, S) each
                out = uncond + guidance * (cond - uncond)
            return self.to_x0(out, x, t)

        return denoise

    @torch.no_grad()
    def sample(
        self,
        net,
        condition: torch.Tensor,
        wrench: torch.Tensor,
        *,
        steps: int = 50,
        sampler: str = "ddim",
        guidance: float = 1.0,
        generator: torch.Generator | None = None,
        same_noise: bool = False,
        autocast: torch.dtype | None = None,
    ) -> torch.Tensor:
        """Tactile images in [−1, 1], (B, 3, S, S), for a batch of conditions, from noise drawn
        with ``generator`` (then the sampler's own noise, from the same stream). ``same_noise``: every
        image of the batch starts from the one initial noise a batch of one would draw (what generating
        them one at a time from the same seed gives, with a sampler that draws no noise of its own).
        ``autocast``: the network's arithmetic (``denoiser``; None: fp32)."""
        if sampler not in SAMPLERS:
            raise ValueError(f"sampler must be one of {', '.join(SAMPLERS)}, got {sampler!r}")
        timesteps = spaced_timesteps(self.cfg.train_timesteps, steps, SPACING[sampler])
        first = 1 if same_noise else condition.shape[0]
        x = torch.randn((first, 3, *condition.shape[2:]), device=condition.device, generator=generator)
        if same_noise:
            x = x.repeat(condition.shape[0], 1, 1, 1)
        denoise = self.denoiser(net, condition, wrench, guidance=guidance, autocast=autocast)
        span = self.cfg.residual_gain if self.cfg.residual else 1.0  # the target's range: ±gain for a residual
        kw = {"clip": span} if sampler in CLIPPED else {}
        out = SAMPLERS[sampler](denoise, x, timesteps, self.alpha_bar, generator=generator, **kw).clamp(-span, span)
        return from_residual(out, condition, span) if self.cfg.residual else out


def to_residual(tactile: torch.Tensor, condition: torch.Tensor, gain: float = 1.0) -> torch.Tensor:
    """Frames in [−1, 1] → their difference from the physics render (the condition's last three
    channels), halved into [−1, 1], times ``gain`` (ModelConfig.residual_gain: into [−gain, gain])."""
    return (tactile - condition[:, -3:]) * (gain / 2)


def from_residual(residual: torch.Tensor, condition: torch.Tensor, gain: float = 1.0) -> torch.Tensor:
    """``to_residual``'s inverse, clamped to the image range."""
    return (condition[:, -3:] + residual * (2 / gain)).clamp(-1.0, 1.0)
