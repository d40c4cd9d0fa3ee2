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


def make_split_dir(tmp_path, n=24, size=16):
    """A small real split: run files via RunWriter, split 8:2."""
    import numpy as np

    from acquisition.run_file import RunHeader, RunWriter
    from dataset.split import make_split
    from protocols.plan import PHASES
    from rig.sim.tactile.indenters import get_indenter

    rng = np.random.default_rng(0)
    header = RunHeader("t", "", "", "sphere10mm", "", "rgb", 14 / size, 1.0, n, (0, 0, 0, 0), PHASES)
    w = RunWriter.create(tmp_path / "r.h5", header, (size, size, 3), get_indenter("sphere10mm").object_image(size, 14 / size),
                         np.zeros((size, size, 3), np.uint8))
    for i in range(n):
        w.append(rng.integers(0, 256, (size, size, 3), dtype=np.uint8), wrench=rng.normal(size=6),
                 pose_commanded=np.zeros(4), pose_measured=np.array([0.1 * i, 0, -1, 0]), t_frame_s=float(i),
                 t_capture_s=float(i), wrench_skew_s=0.0, capture_index=i, step_index=0, phase_index=1, level=1)
    w.set_status("complete")
    w.close()
    make_split([tmp_path / "r.h5"], "8:2", tmp_path / "split")
    return tmp_path / "split"


def test_resume_continues_with_the_same_losses(tmp_path):
    from model.trainer import CheckpointError, TrainConfig, Trainer

    split = make_split_dir(tmp_path)
    cfg = TrainConfig(steps=8, batch_size=4, checkpoint_every=4, seed=3)
    straight = Trainer(SMALL, cfg, split, tmp_path / "a", log=lambda m: None).train()
    first = Trainer(SMALL, cfg, split, tmp_path / "b", log=lambda m: None)
    first.train(until=4)  # saves a checkpoint at step 4
    second = Trainer(SMALL, cfg, split, tmp_path / "b", log=lambda m: None)
    second.resume()
    assert second.step == 4
    resumed = second.train()
    assert resumed == pytest.approx(straight, rel=1e-5)  # same data order, noise, optimizer state
    other = ModelConfig(**{**SMALL.__dict__, "block_out_channels": (16, 16)})
    with pytest.raises(CheckpointError, match="different model config"):
        Trainer(other, cfg, split, tmp_path / "b", log=lambda m: None).resume()


def trained_run(tmp_path, steps):
    """A split and a tiny run trained on it for ``steps`` steps, saved: (split dir, run dir)."""
    from model.trainer import TrainConfig, Trainer

    split = make_split_dir(tmp_path)
    trainer = Trainer(SMALL, TrainConfig(steps=steps, batch_size=4, checkpoint_every=100), split, tmp_path / "run",
                      log=lambda m: None)
    trainer.train()
    trainer.save()
    return split, tmp_path / "run"


def test_generate_from_a_trained_run(tmp_path):
    import numpy as np

    from model.inference import TrainedModel
    from model.trainer import CheckpointError

    _, run = trained_run(tmp_path, 3)
    model = TrainedModel.load(run)
    obj = np.full((40, 40, 3), 200, np.uint8)
    a = model.generate(obj, [0, 0, 2, 0, 0, 0], (0.2, 0.0, 5.0), steps=4, seed=1)
    b = model.generate(obj, [0, 0, 2, 0, 0, 0], (0.2, 0.0, 5.0), steps=4, seed=1)
    assert a.shape == (16, 16, 3) and a.dtype == np.uint8 and np.array_equal(a, b)
    with pytest.raises(ValueError, match="six finite numbers"):
        model.generate(obj, [0, 0, float("nan"), 0, 0, 0])
    with pytest.raises(CheckpointError, match="no checkpoint"):
        TrainedModel.load(tmp_path / "elsewhere")


def test_evaluate_writes_the_metrics_table(tmp_path):
    from model.evaluate import evaluate, report

    split, run = trained_run(tmp_path, 2)
    rows = evaluate(run, split, settings=(("ddim", 3), ("ddpm", 4)), limit=3)
    assert [r.setting for r in rows] == ["ddim, 3 steps", "ddpm, 4 steps"]
    for r in rows:
        assert r.images == 3 and r.mse > 0 and 0 < r.psnr < 60 and -1 <= r.ssim <= 1 and r.seconds_per_image > 0
    text = report(rows, tmp_path / "report", title="test").read_text()
    assert "| this model (ddim, 3 steps, 3 images) |" in text and "| paper, RGB light (paper's table, real data) | 21.0 |" in text
