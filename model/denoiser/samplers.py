"""Samplers: short pure functions with one signature, as in k-diffusion and EDM.

    sample_X(denoise, x_T, timesteps, alpha_bar, *, generator=None, ...) -> x_0

``denoise(x_t, t) -> x̂₀`` (B, C, H, W) is a closure over the network, the condition and
the guidance (``Diffusion.denoiser``): whatever the network predicts (y₀, ε or v), the
samplers see the clean-image estimate D(x_t, t). ``timesteps`` are descending training
steps; each step goes from one to the next and the last goes to the clean image
(ᾱ = 1). ``alpha_bar`` is the schedule's ᾱ_t, indexed by training step. Notation: for a
step from t to s, a_t = ᾱ_t, ε̂ = (x_t − √a_t·x̂₀)/√(1 − a_t) (Ho et al. 2020 eq. 4 solved
for ε).
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np
import torch

Denoise = Callable[[torch.Tensor, int], torch.Tensor]


def _steps(timesteps: Sequence[int], alpha_bar: torch.Tensor):
    """(t, a_t, a_s) for each step t → s; after the last timestep, s is the clean image (a_s = 1)."""
    ts = [int(t) for t in timesteps]
    for i, t in enumerate(ts):
        yield t, float(alpha_bar[t]), float(alpha_bar[ts[i + 1]]) if i + 1 < len(ts) else 1.0


def _noise(x: torch.Tensor, generator: torch.Generator | None) -> torch.Tensor:
    return torch.randn(x.shape, generator=generator, device=x.device, dtype=x.dtype)


def sample_ddim(
    denoise: Denoise,
    x: torch.Tensor,
    timesteps: Sequence[int],
    alpha_bar: torch.Tensor,
    *,
    generator: torch.Generator | None = None,
    eta: float = 0.0,
    clip: float | None = 1.0,
) -> torch.Tensor:
    """DDIM, Song et al. 2021 eq. 12:
    x_s = √a_s·x̂₀ + √(1 − a_s − σ²)·ε̂ + σ·z,  σ = η·√((1 − a_s)/(1 − a_t))·√(1 − a_t/a_s) (eq. 16).
    η = 0 is deterministic; η = 1 is DDPM's ancestral step (``sample_ddpm``). x̂₀ is clipped to
    [−clip, clip] (the data's range; None: not) after ε̂ is taken from it, as the DDIM and
    diffusers code do."""
    for t, a_t, a_s in _steps(timesteps, alpha_bar):
        x0 = denoise(x, t)
        eps = (x - math.sqrt(a_t) * x0) / math.sqrt(1.0 - a_t)
        if clip is not None:
            x0 = x0.clamp(-clip, clip)
        sigma = eta * math.sqrt((1.0 - a_s) / (1.0 - a_t) * (1.0 - a_t / a_s))
        x = math.sqrt(a_s) * x0 + math.sqrt(max(1.0 - a_s - sigma**2, 0.0)) * eps
        if sigma > 0:
            x = x + sigma * _noise(x, generator)
    return x


def sample_ddpm(
    denoise: Denoise,
    x: torch.Tensor,
    timesteps: Sequence[int],
    alpha_bar: torch.Tensor,
    *,
    generator: torch.Generator | None = None,
    clip: float | None = 1.0,
) -> torch.Tensor:
    """DDPM ancestral sampling, Ho et al. 2020 Alg. 2 with the posterior of eq. 6–7 (over strided
    steps t → s, with α = a_t/a_s and β = 1 − α):
    x_s = √a_s·β/(1 − a_t)·x̂₀ + √α·(1 − a_s)/(1 − a_t)·x_t + σ·z,  σ² = β̃ = (1 − a_s)/(1 − a_t)·β.
    The last step (a_s = 1) has σ = 0 and draws no noise. x̂₀ is clipped to [−clip, clip] (None: not)."""
    for t, a_t, a_s in _steps(timesteps, alpha_bar):
        x0 = denoise(x, t)
        if clip is not None:
            x0 = x0.clamp(-clip, clip)
        alpha = a_t / a_s
        beta = 1.0 - alpha
        mean = (math.sqrt(a_s) * beta / (1.0 - a_t)) * x0 + (math.sqrt(alpha) * (1.0 - a_s) / (1.0 - a_t)) * x
        var = (1.0 - a_s) / (1.0 - a_t) * beta
        x = mean + math.sqrt(var) * _noise(x, generator) if var > 0 else mean
    return x


def sample_dpm(
    denoise: Denoise,
    x: torch.Tensor,
    timesteps: Sequence[int],
    alpha_bar: torch.Tensor,
    *,
    generator: torch.Generator | None = None,
    order: int = 2,
) -> torch.Tensor:
    """DPM-Solver++(2M), Lu et al. 2022 ("DPM-Solver++", Alg. 2), data prediction, multistep.
    With α = √a, σ = √(1 − a), λ = log(α/σ) and h = λ_s − λ_t:
    x_s = (σ_s/σ_t)·x_t − α_s·(e^(−h) − 1)·D,  D = x̂₀ + (x̂₀ − x̂₀_prev)/(2r),  r = h_prev/h.
    The first step, and the last (σ_s = 0: x_s = x̂₀), are first order, D = x̂₀, which is DDIM
    with η = 0 (the paper's §4.1); ``order=1`` keeps every step first order. x̂₀ is not clipped
    (diffusers' solver without thresholding). ``generator`` is unused (a deterministic solver),
    kept for the shared signature."""
    if order not in (1, 2):
        raise ValueError(f"DPM-Solver++ order must be 1 or 2, got {order}")
    prev_x0, prev_lam = None, 0.0
    for t, a_t, a_s in _steps(timesteps, alpha_bar):
        x0 = denoise(x, t)
        lam_t = 0.5 * math.log(a_t / (1.0 - a_t))
        if a_s >= 1.0:  # to the clean image: σ_s = 0, e^(−h) = 0
            x = x0
            continue
        lam_s = 0.5 * math.log(a_s / (1.0 - a_s))
        h = lam_s - lam_t
        d = x0
        if order == 2 and prev_x0 is not None:
            r = (lam_t - prev_lam) / h
            d = x0 + (x0 - prev_x0) / (2.0 * r)
        x = math.sqrt((1.0 - a_s) / (1.0 - a_t)) * x - math.sqrt(a_s) * math.expm1(-h) * d
        prev_x0, prev_lam = x0, lam_t
    return x


SAMPLERS: dict[str, Callable[..., torch.Tensor]] = {"ddim": sample_ddim, "ddpm": sample_ddpm, "dpm": sample_dpm}
CLIPPED = frozenset({"ddim", "ddpm"})  # the samplers that clip x̂₀ to the data's range (their ``clip``)
DETERMINISTIC = frozenset({"ddim", "dpm"})  # the samplers that draw no noise after the initial one (DDIM at η 0)
# Where each sampler's steps fall: diffusers' defaults for these schedulers, which made the
# docs' numbers. "leading": 0, T/n, 2T/n, ... (ends at t = 0); "linspace": T−1 down to T/n.
SPACING = {"ddim": "leading", "ddpm": "leading", "dpm": "linspace"}


def spaced_timesteps(train_timesteps: int, steps: int, spacing: str) -> list[int]:
    """``steps`` descending training steps out of ``train_timesteps``."""
    if not 1 <= steps <= train_timesteps:
        raise ValueError(f"sampler steps must be in [1, {train_timesteps}] (the training steps), got {steps}")
    if spacing == "leading":
        ts = np.arange(steps) * (train_timesteps // steps)
    elif spacing == "linspace":
        ts = np.linspace(0, train_timesteps - 1, steps + 1).round()[1:].astype(int)
    else:
        raise ValueError(f"spacing must be leading or linspace, got {spacing!r}")
    return [int(t) for t in ts[::-1]]
