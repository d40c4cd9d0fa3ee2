"""The samplers against each other, against diffusers' schedulers (what sampled before), and
classifier-free guidance in one batch against two passes."""

from __future__ import annotations

import pytest
import torch

from model.denoiser.config import ModelConfig
from model.denoiser.diffusion import Diffusion, alpha_bar_schedule
from model.denoiser.samplers import SAMPLERS, SPACING, sample_ddim, sample_ddpm, sample_dpm, spaced_timesteps

# diffusers' DPM scheduler trips a numpy 2 deprecation inside itself; not ours to fix
pytestmark = pytest.mark.filterwarnings("ignore:__array__ implementation:DeprecationWarning")

T = 1000
AB = alpha_bar_schedule("squaredcos_cap_v2", T)


def toy_x0(x: torch.Tensor, t: int) -> torch.Tensor:
    """A denoiser that depends on x_t and t nonlinearly, as a network does, and strays outside
    the data's [−1, 1] (where DDIM and DDPM clip it)."""
    return 1.3 * torch.tanh(0.7 * x + 0.3 * torch.sin(3 * x) + t / T)


def start(seed=0, shape=(2, 3, 8, 8)):
    return torch.randn(shape, generator=torch.Generator().manual_seed(seed))


def test_the_schedule_is_diffusers_cosine():
    from diffusers import DDPMScheduler

    for name in ("squaredcos_cap_v2", "linear", "scaled_linear"):
        ref = DDPMScheduler(num_train_timesteps=T, beta_schedule=name).alphas_cumprod
        assert torch.allclose(alpha_bar_schedule(name, T), ref, rtol=1e-5, atol=1e-9), name
    with pytest.raises(ValueError, match="beta_schedule must be"):
        alpha_bar_schedule("sigmoid", T)


@pytest.mark.parametrize("steps", [1, 3, 10, 50])
def test_timesteps_are_diffusers_grids(steps):
    from diffusers import DDIMScheduler, DDPMScheduler, DPMSolverMultistepScheduler

    kinds = {"ddim": DDIMScheduler, "ddpm": DDPMScheduler, "dpm": DPMSolverMultistepScheduler}
    base = DDPMScheduler(num_train_timesteps=T, beta_schedule="squaredcos_cap_v2")
    for name, kind in kinds.items():
        sched = kind.from_config(base.config)
        sched.set_timesteps(steps)
        assert spaced_timesteps(T, steps, SPACING[name]) == sched.timesteps.tolist(), name
    with pytest.raises(ValueError, match=r"steps must be in \[1, 1000\]"):
        spaced_timesteps(T, 1001, "leading")


def diffusers_loop(name, denoise, x, steps, generator, clip=True):
    """The loop model/denoiser/diffusion.py ran before (diffusers' schedulers from its DDPM config)."""
    from diffusers import DDIMScheduler, DDPMScheduler, DPMSolverMultistepScheduler

    base = DDPMScheduler(
        num_train_timesteps=T, beta_schedule="squaredcos_cap_v2", prediction_type="sample", clip_sample=clip
    )
    sched = {"ddim": DDIMScheduler, "ddpm": DDPMScheduler, "dpm": DPMSolverMultistepScheduler}[name].from_config(
        base.config
    )
    sched.set_timesteps(steps)
    for t in sched.timesteps:
        out = denoise(x, int(t))
        extra = {"generator": generator} if name != "dpm" else {}  # the solver takes no generator
        x = sched.step(out, t, x, **extra).prev_sample
    return x


@pytest.mark.parametrize("name", ["ddim", "ddpm", "dpm"])
@pytest.mark.parametrize("steps", [1, 4, 20])
def test_each_sampler_matches_the_diffusers_scheduler_it_replaces(name, steps):
    """Same start, same noise stream: the frames the old code made, x̂₀ clipping included (and without)."""
    ts = spaced_timesteps(T, steps, SPACING[name])
    ours = SAMPLERS[name](toy_x0, start(), ts, AB, generator=torch.Generator().manual_seed(5))
    theirs = diffusers_loop(name, toy_x0, start(), steps, torch.Generator().manual_seed(5))
    assert torch.allclose(ours, theirs, atol=1e-4), (ours - theirs).abs().max()
    if name != "dpm":  # the solver never clipped
        unclipped = SAMPLERS[name](toy_x0, start(), ts, AB, generator=torch.Generator().manual_seed(5), clip=None)
        theirs = diffusers_loop(name, toy_x0, start(), steps, torch.Generator().manual_seed(5), clip=False)
        assert torch.allclose(unclipped, theirs, atol=1e-4)
        assert steps == 1 or (unclipped - ours).abs().max() > 1e-3  # the toy needs the clip


def test_ddim_with_eta_one_is_ddpm():
    """η = 1 makes DDIM's step the DDPM posterior q(x_s | x_t, x̂₀) (Song et al. 2021 §4.1)."""
    ts = spaced_timesteps(T, 10, "leading")
    a = sample_ddim(toy_x0, start(), ts, AB, eta=1.0, generator=torch.Generator().manual_seed(2), clip=None)
    b = sample_ddpm(toy_x0, start(), ts, AB, generator=torch.Generator().manual_seed(2), clip=None)
    assert torch.allclose(a, b, atol=1e-5)
    c = sample_ddim(toy_x0, start(), ts, AB, eta=0.0, generator=torch.Generator().manual_seed(2))
    assert (a - c).abs().max() > 1e-2  # and η = 0 is a different (deterministic) path


def test_first_order_dpm_solver_is_ddim_and_second_order_is_not():
    """DPM-Solver++(1) is DDIM with η = 0 (Lu et al. 2022 §4.1); the second-order correction changes it."""
    ts = spaced_timesteps(T, 8, "linspace")
    ddim = sample_ddim(toy_x0, start(), ts, AB, clip=None)
    assert torch.allclose(sample_dpm(toy_x0, start(), ts, AB, order=1), ddim, atol=1e-5)
    assert (sample_dpm(toy_x0, start(), ts, AB) - ddim).abs().max() > 1e-3
    with pytest.raises(ValueError, match="order must be 1 or 2"):
        sample_dpm(toy_x0, start(), ts, AB, order=3)


def test_deterministic_samplers_draw_no_noise_and_ddpm_skips_the_last_draw():
    """A shared generator's stream stays where the old schedulers left it: DDIM (η = 0) and DPM-Solver
    draw nothing, DDPM one batch of noise per step but the last."""
    for name, draws in (("ddim", 0), ("dpm", 0), ("ddpm", 4)):
        g = torch.Generator().manual_seed(1)
        SAMPLERS[name](toy_x0, start(), spaced_timesteps(T, 5, SPACING[name]), AB, generator=g)
        ref = torch.Generator().manual_seed(1)
        for _ in range(draws):
            torch.randn((2, 3, 8, 8), generator=ref)
        assert torch.equal(torch.randn(3, generator=g), torch.randn(3, generator=ref)), name


@pytest.mark.parametrize("name", ["ddim", "ddpm", "dpm"])
def test_a_perfect_denoiser_gives_back_the_clean_image_at_any_step_count(name):
    clean = torch.rand(2, 3, 8, 8) * 1.6 - 0.8
    for steps in (1, 7, 50):
        out = SAMPLERS[name](
            lambda x, t: clean,
            start(),
            spaced_timesteps(T, steps, SPACING[name]),
            AB,
            generator=torch.Generator().manual_seed(0),
        )
        assert torch.allclose(out, clean, atol=1e-5), (name, steps)


class Counting(torch.nn.Module):
    """A conditional toy network that counts its forward passes and the batch each one saw."""

    def __init__(self):
        super().__init__()
        self.conv = torch.nn.Conv2d(6, 3, 3, padding=1)
        self.lin = torch.nn.Linear(6, 3)
        self.calls: list[int] = []

    def forward(self, noisy, t, condition, wrench):
        self.calls.append(noisy.shape[0])
        return torch.tanh(
            self.conv(torch.cat([noisy, condition], 1))
            + self.lin(wrench)[:, :, None, None]
            + t[:, None, None, None] / 1000
        )


@pytest.mark.parametrize("prediction", ["sample", "epsilon", "v_prediction"])
def test_guidance_in_one_batch_equals_two_separate_passes(prediction):
    torch.manual_seed(0)
    net = Counting()
    diff = Diffusion(ModelConfig(image_size=8, block_out_channels=(8,), train_timesteps=T, prediction=prediction))
    cond, wrench, x = torch.rand(3, 3, 8, 8) * 2 - 1, torch.randn(3, 6), start(shape=(3, 3, 8, 8))
    w, t = 2.5, 600
    with torch.no_grad():
        guided = diff.denoiser(net, cond, wrench, guidance=w)(x, t)
        assert net.calls == [6]  # one pass over both halves
        tt = torch.full((3,), t)
        c = net(x, tt, cond, wrench)
        u = net(x, tt, torch.zeros_like(cond), torch.zeros_like(wrench))
        two = diff.to_x0(u + w * (c - u), x, t)
    assert torch.allclose(guided, two, atol=1e-5)
    net.calls.clear()
    with torch.no_grad():
        diff.sample(net, cond, wrench, steps=4, guidance=w, generator=torch.Generator().manual_seed(0))
        assert net.calls == [6] * 4  # one forward pass per step
        net.calls.clear()
        diff.sample(net, cond, wrench, steps=4, generator=torch.Generator().manual_seed(0))
        assert net.calls == [3] * 4  # no guidance: the conditional half only


def test_guidance_one_is_the_conditional_prediction():
    torch.manual_seed(0)
    net = Counting()
    diff = Diffusion(ModelConfig(image_size=8, block_out_channels=(8,), train_timesteps=T))
    cond, wrench, x = torch.rand(2, 3, 8, 8), torch.randn(2, 6), start()
    with torch.no_grad():
        out = diff.denoiser(net, cond, wrench)(x, 300)
        assert torch.equal(out, net(x, torch.full((2,), 300), cond, wrench))
