"""The trainer knows the network only through the diffusion loss; callbacks; the network registry."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from model.denoiser.config import ModelConfig
from model.denoiser.precision import cpu_has_native_bf16
from model.training.trainer import Callback, TrainConfig, Trainer
from tests.test_model_core import SMALL, make_split_dir


class Recorder(Callback):
    def __init__(self):
        self.events: list[tuple[str, int]] = []

    def on_train_start(self, trainer):
        self.events.append(("start", trainer.step))

    def on_step_end(self, trainer):
        self.events.append(("step", trainer.step))

    def on_train_end(self, trainer):
        self.events.append(("end", trainer.step))


class LinearLoss:
    """A 'diffusion' for any network: the trainer must need nothing else from it."""

    def __init__(self):
        self.batches: list[torch.Tensor] = []

    def batch_loss(self, net, batch, generator=None):
        self.batches.append(batch["x"])
        noise = torch.randn(batch["x"].shape, generator=generator)
        return ((net(batch["x"] + 0.01 * noise) - batch["y"]) ** 2).mean()


def toy_data(n=12):
    g = torch.Generator().manual_seed(0)
    x = torch.randn(n, 3, generator=g)
    return [{"x": x[i], "y": x[i].sum(0, keepdim=True), "index": i} for i in range(n)]


def test_the_trainer_trains_any_network_through_the_loss_and_fires_its_callbacks():
    torch.manual_seed(0)
    rec, loss = Recorder(), LinearLoss()
    cfg = TrainConfig(steps=5, batch_size=4, seed=1)
    trainer = Trainer(cfg, torch.nn.Linear(3, 1), loss, toy_data(), [rec], device="cpu")
    losses = trainer.train(until=3)
    assert rec.events == [("start", 0), ("step", 1), ("step", 2), ("step", 3), ("end", 3)]
    assert len(losses) == 3 and trainer.step == 3
    # each step's batch is the data order's, stacked (non-tensor fields left out)
    assert torch.equal(loss.batches[1], torch.stack([toy_data()[int(i)]["x"] for i in trainer.batch_indices(1)]))
    # state() / load_state(): a second trainer continues exactly where the first is
    saved = trainer.state()
    straight = trainer.train()
    other = Trainer(cfg, torch.nn.Linear(3, 1), LinearLoss(), toy_data(), device="cpu")
    other.load_state(saved)
    assert other.train() == pytest.approx(straight, rel=1e-6)
    with pytest.raises(ValueError, match="nothing to resume from"):
        other.resume()
    assert other.save() is None  # no checkpoint callback: nothing saved


def test_a_batch_larger_than_the_data_is_refused():
    with pytest.raises(ValueError, match="fewer than one batch"):
        Trainer(TrainConfig(batch_size=16), torch.nn.Linear(3, 1), LinearLoss(), toy_data(8), device="cpu")


class TinyConv(torch.nn.Module):
    """Another network, as the registry's recipe writes one: built from a ModelConfig, it
    returns the prediction target from (noisy, t, condition, wrench)."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.conv = torch.nn.Conv2d(7, 3, 3, padding=1)

    def forward(self, noisy, timesteps, condition, wrench):
        from model.denoiser.network import check_inputs, wrench_plane

        check_inputs(noisy, condition, wrench)
        x = torch.cat([noisy, condition, wrench_plane(wrench, noisy.shape[-1])], 1)  # (B, 7, S, S)
        return self.conv(x) + timesteps[:, None, None, None] / 1000


def test_a_network_from_the_registry_trains_saves_and_generates(tmp_path, monkeypatch):
    from model.denoiser import registry
    from model.generation.inference import TrainedModel
    from model.training.build import build

    monkeypatch.setitem(registry.NETWORKS, "tinyconv", TinyConv)
    cfg = dataclasses.replace(SMALL, network="tinyconv")
    split = make_split_dir(tmp_path)
    trainer = build(
        cfg,
        TrainConfig(steps=2, batch_size=4, sample_every=1, samples=2, sample_steps=2),
        split,
        tmp_path / "run",
        log=lambda m: None,
    )
    assert isinstance(trainer.ema, TinyConv)
    trainer.train()
    trainer.save()
    assert (tmp_path / "run" / "samples" / "step-000002.png").exists()
    model = TrainedModel.load(tmp_path / "run")
    assert isinstance(model.net, TinyConv)
    frame = model.generate(np.full((40, 40, 3), 200, np.uint8), [0, 0, 2, 0, 0, 0], steps=2)
    assert frame.shape == (16, 16, 3)


def test_an_unknown_network_is_named():
    from model.denoiser.registry import build_network

    with pytest.raises(ValueError, match="network must be one of unet2d, got 'transformer'"):
        build_network(dataclasses.replace(SMALL, network="transformer"))


def test_progress_lines_every_fifty_steps_and_at_the_end():
    from model.training.callbacks import Progress

    lines: list[str] = []
    trainer = Trainer(
        TrainConfig(batch_size=4),
        torch.nn.Linear(3, 1),
        LinearLoss(),
        toy_data(),
        [Progress(lines.append, every=2)],
        device="cpu",
    )
    trainer.train(until=5)
    assert [line.split("  ")[0] for line in lines] == ["step 2/5", "step 4/5", "step 5/5"]
    assert all("images/s" in line for line in lines)


@pytest.mark.skipif(not cpu_has_native_bf16(), reason="no native bf16 here")
def test_bf16_on_the_cpu_trains_the_same_network_about_as_far_as_fp32():
    """The same ten steps in bf16 and in fp32 from the same weights and data: the losses agree to a few
    per cent (bf16 keeps 8 bits of mantissa in the products; the weights stay fp32)."""
    from model.denoiser.config import preset
    from model.denoiser.diffusion import Diffusion
    from model.denoiser.registry import build_network

    cfg = preset("tiny", conditioning="plane+embedding", image_size=16)
    gen = torch.Generator().manual_seed(3)
    batch = {
        "tactile": torch.randint(0, 255, (8, 3, 16, 16), dtype=torch.uint8, generator=gen),
        "condition": torch.randint(0, 255, (8, 3, 16, 16), dtype=torch.uint8, generator=gen),
        "wrench": torch.randn(8, 6, generator=gen),
    }
    losses = {}
    for bf16 in (False, True):
        torch.manual_seed(0)
        net, diffusion = build_network(cfg), Diffusion(cfg)
        opt = torch.optim.Adam(net.parameters(), lr=1e-3)
        noise = torch.Generator().manual_seed(1)
        run = []
        for _ in range(10):
            with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
                loss = diffusion.batch_loss(net, batch, generator=noise)
            opt.zero_grad()
            loss.backward()
            opt.step()
            run.append(float(loss.detach()))
        losses[bf16] = np.array(run)
        assert all(p.dtype == torch.float32 for p in net.parameters())
    assert losses[True][-1] < losses[True][0]  # it learns
    np.testing.assert_allclose(losses[True], losses[False], rtol=0.05)
