"""Diffusion maths apart from the network: the training loss and the samplers.

Loss (paper §III-B, Palette/SR3): E‖ε − f_θ(x, y_t, t)‖² with y_t = √ᾱ_t·y₀ + √(1−ᾱ_t)·ε.
``ModelConfig.prediction`` may instead target v = √ᾱ_t·ε − √(1−ᾱ_t)·y₀ or y₀ (the same
noise process; the samplers read the target from the scheduler config).
Condition dropout replaces (object image, wrench) by zeros for classifier-free
guidance: ε̂ = ε_u + w·(ε_c − ε_u).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from model.config import ModelConfig

SAMPLERS = ("ddim", "ddpm", "dpm")


class Diffusion:
    def __init__(self, cfg: ModelConfig):
        from diffusers import DDPMScheduler

        self.cfg = cfg
        self.train_scheduler = DDPMScheduler(num_train_timesteps=cfg.train_timesteps, beta_schedule=cfg.beta_schedule,
                                             prediction_type=cfg.prediction)

    def loss(self, net, tactile: torch.Tensor, condition: torch.Tensor, wrench: torch.Tensor,
             generator: torch.Generator | None = None) -> torch.Tensor:
        """Mean ε-prediction error for a batch of clean tactile images in [−1, 1]."""
        b = tactile.shape[0]
        dev = tactile.device
        t = torch.randint(0, self.cfg.train_timesteps, (b,), device=dev, generator=generator)
        noise = torch.randn(tactile.shape, device=dev, generator=generator)
        noisy = self.train_scheduler.add_noise(tactile, noise, t)
        if self.cfg.cond_dropout > 0:
            keep = (torch.rand((b,), device=dev, generator=generator) >= self.cfg.cond_dropout).float()
            condition = condition * keep[:, None, None, None]
            wrench = wrench * keep[:, None]
        if self.cfg.prediction == "epsilon":
            target = noise
        elif self.cfg.prediction == "v_prediction":
            target = self.train_scheduler.get_velocity(tactile, noise, t)
        else:
            target = tactile
        return F.mse_loss(net(noisy, t, condition, wrench), target)

    def scheduler(self, name: str):
        from diffusers import DDIMScheduler, DDPMScheduler, DPMSolverMultistepScheduler

        kinds = {"ddim": DDIMScheduler, "ddpm": DDPMScheduler, "dpm": DPMSolverMultistepScheduler}
        if name not in kinds:
            raise ValueError(f"sampler must be one of {', '.join(SAMPLERS)}, got {name!r}")
        return kinds[name].from_config(self.train_scheduler.config)

    @torch.no_grad()
    def sample(self, net, condition: torch.Tensor, wrench: torch.Tensor, *, steps: int = 50, sampler: str = "ddim",
               guidance: float = 1.0, generator: torch.Generator | None = None) -> torch.Tensor:
        """Tactile images in [−1, 1], (B, 3, S, S), for a batch of conditions."""
        sched = self.scheduler(sampler)
        sched.set_timesteps(steps, device=condition.device)
        x = torch.randn(condition.shape, device=condition.device, generator=generator)
        x = x * sched.init_noise_sigma
        uncond_c, uncond_w = torch.zeros_like(condition), torch.zeros_like(wrench)
        for t in sched.timesteps:
            tt = torch.full((x.shape[0],), int(t), device=x.device, dtype=torch.long)
            inp = sched.scale_model_input(x, t)
            eps = net(inp, tt, condition, wrench)
            if guidance != 1.0:
                eps_u = net(inp, tt, uncond_c, uncond_w)
                eps = eps_u + guidance * (eps - eps_u)
            x = sched.step(eps, t, x, generator=generator).prev_sample if sampler != "dpm" else sched.step(eps, t, x).prev_sample
        return x.clamp(-1.0, 1.0)
