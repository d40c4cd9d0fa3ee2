"""The denoiser and the diffusion maths, on CPU with a tiny configuration."""

import pytest
import torch

from model.config import ModelConfig, preset
from model.diffusion import Diffusion
from model.network import ContactDenoiser, wrench_plane

SMALL = ModelConfig(image_size=16, block_out_channels=(16, 32), layers_per_block=1, train_timesteps=100, cond_dropout=0.0)


def pairs(n=4, size=16, seed=0):
    """Tactile images that depend on the condition: a blob at the object's place, bright with Fz."""
    g = torch.Generator().manual_seed(seed)
    cond = torch.zeros(n, 3, size, size)
    tactile = torch.full((n, 3, size, size), -0.5)
    wrench = torch.randn(n, 6, generator=g)
    for i in range(n):
        r, c = 4 + 3 * (i % 3), 4 + 2 * i % 8
        cond[i, :, r:r + 4, c:c + 4] = 1.0
        tactile[i, 0, r:r + 4, c:c + 4] = torch.tanh(wrench[i, 2])
    return tactile, cond, wrench


@pytest.mark.parametrize("conditioning", ["plane", "embedding", "plane+embedding"])
def test_shapes(conditioning):
    cfg = ModelConfig(**{**SMALL.__dict__, "conditioning": conditioning})
    net = ContactDenoiser(cfg)
    tactile, cond, wrench = pairs()
    out = net(tactile, torch.tensor([1, 5, 10, 50]), cond, wrench)
    assert out.shape == tactile.shape


def test_wrench_plane_stripes():
    p = wrench_plane(torch.arange(6.0)[None], 12)
    assert p.shape == (1, 1, 12, 12) and p[0, 0, 3, :].tolist() == [0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5]


def test_bad_wrenches_and_mismatched_images_are_clear_errors():
    net = ContactDenoiser(SMALL)
    tactile, cond, wrench = pairs()
    t = torch.zeros(4, dtype=torch.long)
    for bad, words in ((wrench[:, :5], "must be \\(batch, 6\\)"), (wrench * float("nan"), "NaN"),
                       (wrench * 1e6, "absurd")):
        with pytest.raises(ValueError, match=words):
            net(tactile, t, cond, bad)
    with pytest.raises(ValueError, match="must match the tactile image"):
        net(tactile, t, cond[:, :, :8, :8], wrench)


def test_loss_falls_when_training_on_a_handful_of_pairs():
    torch.manual_seed(0)
    net = ContactDenoiser(SMALL)
    diffusion = Diffusion(SMALL)
    opt = torch.optim.Adam(net.parameters(), lr=2e-3)
    tactile, cond, wrench = pairs()
    g = torch.Generator().manual_seed(1)
    losses = []
    for _ in range(120):
        loss = diffusion.loss(net, tactile, cond, wrench, generator=g)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    first, last = sum(losses[:20]) / 20, sum(losses[-20:]) / 20
    assert last < 0.5 * first, (first, last)


def test_sampling_is_deterministic_under_a_seed():
    net = ContactDenoiser(SMALL).eval()
    diffusion = Diffusion(SMALL)
    _, cond, wrench = pairs(2)
    a = diffusion.sample(net, cond, wrench, steps=5, generator=torch.Generator().manual_seed(7))
    b = diffusion.sample(net, cond, wrench, steps=5, generator=torch.Generator().manual_seed(7))
    c = diffusion.sample(net, cond, wrench, steps=5, generator=torch.Generator().manual_seed(8))
    assert torch.equal(a, b) and not torch.equal(a, c) and a.shape == cond.shape
    with pytest.raises(ValueError, match="sampler must be one of"):
        diffusion.sample(net, cond, wrench, steps=2, sampler="euler")


def test_presets_and_config_errors():
    assert preset("tiny").image_size == 32 and preset("paper").image_size == 256
    with pytest.raises(KeyError, match="tiny"):
        preset("huge")
    with pytest.raises(ValueError, match="divisible"):
        ModelConfig(image_size=30, block_out_channels=(8, 16, 32))
    with pytest.raises(ValueError, match="conditioning"):
        ModelConfig(conditioning="telepathy")
