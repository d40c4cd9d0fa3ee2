"""The network's arithmetic: bf16 only where the CPU multiplies it natively, for training and for
sampling alike; anything else asked of a CPU is refused in one line; sampled frames in bf16 stay
within a grey level or two of fp32 from the same weights and noise."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from model.denoiser import precision as P


def test_cpu_precision_is_bf16_only_where_the_cpu_has_it_natively(monkeypatch):
    """auto on the CPU: bf16 where oneDNN multiplies bf16 natively, fp32 elsewhere; bf16 asked of a
    CPU without it, and fp16 on any CPU, are refused in one line naming the choice."""
    monkeypatch.setattr(P.torch.cuda, "is_available", lambda: False)
    cpu = torch.device("cpu")
    for native in (True, False):
        monkeypatch.setattr(P, "cpu_has_native_bf16", lambda native=native: native)
        assert P.training_precision("auto", "cpu") == ("bf16" if native else "no")
        assert P.training_precision("no", "cpu") == "no"
        assert P.sampling_dtype("auto", cpu) == (torch.bfloat16 if native else None)
        assert P.sampling_dtype("no", cpu) is None
    monkeypatch.setattr(P, "cpu_has_native_bf16", lambda: True)
    assert P.training_precision("bf16", None) == "bf16"
    assert P.sampling_dtype("bf16", cpu) == torch.bfloat16
    for ask in (lambda c: P.training_precision(c, "cpu"), lambda c: P.sampling_dtype(c, cpu)):
        with pytest.raises(ValueError, match="mixed_precision fp16: this CPU has no native fp16"):
            ask("fp16")
    monkeypatch.setattr(P, "cpu_has_native_bf16", lambda: False)
    for ask in (lambda c: P.training_precision(c, "cpu"), lambda c: P.sampling_dtype(c, cpu)):
        with pytest.raises(ValueError, match="mixed_precision bf16: this CPU has no native bf16"):
            ask("bf16")
        with pytest.raises(ValueError, match="must be auto, no, fp16 or bf16"):
            ask("fp8")
    assert P.arithmetic_words(None) == "fp32" and P.arithmetic_words(torch.bfloat16) == "bf16 autocast"


def test_validation_samples_run_in_the_arithmetic_the_network_trains_in():
    """accelerate's mixed_precision → the autocast of the training's validation samples: fp16 training
    on a GPU samples in fp16 too (it used to fall back to fp32); anything else is refused."""
    assert P.autocast_dtype("no") is None
    assert P.autocast_dtype("bf16") == torch.bfloat16
    assert P.autocast_dtype("fp16") == torch.float16
    with pytest.raises(ValueError, match="must be no, bf16 or fp16, got 'auto'"):
        P.autocast_dtype("auto")
    gpu = torch.device("cuda")
    assert P.sampling_dtype("fp16", gpu) == torch.float16 and P.sampling_dtype("auto", gpu) is None


@pytest.mark.skipif(not P.cpu_has_native_bf16(), reason="no native bf16 here")
def test_bf16_sampling_gives_the_fp32_frames_to_a_grey_level_or_two():
    """Ten DDIM steps of a briefly trained tiny network from the same noise, in bf16 autocast and in
    fp32: the frames agree to a few grey levels at most and under one on average (0–255), and the
    network's weights stay fp32."""
    from dataset.torch_dataset import tensor_to_image
    from model.denoiser.config import preset
    from model.denoiser.diffusion import Diffusion
    from model.denoiser.registry import build_network

    cfg = preset("tiny", conditioning="plane+embedding", image_size=16)
    torch.manual_seed(0)
    net, diffusion = build_network(cfg), Diffusion(cfg)
    gen = torch.Generator().manual_seed(3)
    batch = {
        "tactile": torch.randint(0, 255, (8, 3, 16, 16), dtype=torch.uint8, generator=gen),
        "condition": torch.randint(0, 255, (8, 3, 16, 16), dtype=torch.uint8, generator=gen),
        "wrench": torch.randn(8, 6, generator=gen),
    }
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    for _ in range(5):  # weights that are not the initial ones
        loss = diffusion.batch_loss(net, batch, generator=gen)
        opt.zero_grad()
        loss.backward()
        opt.step()
    net.eval()
    cond = batch["condition"].float() / 127.5 - 1
    frames = {}
    for dtype in (None, torch.bfloat16):
        out = diffusion.sample(
            net, cond, batch["wrench"], steps=10, generator=torch.Generator().manual_seed(7), autocast=dtype
        )
        assert out.dtype == torch.float32
        frames[dtype] = np.stack([tensor_to_image(x).astype(float) for x in out])
    diff = np.abs(frames[torch.bfloat16] - frames[None])
    assert diff.mean() < 1.0 and diff.max() <= 8, (diff.mean(), diff.max())
    assert diff.max() > 0  # it did run in bf16
    assert all(p.dtype == torch.float32 for p in net.parameters())
