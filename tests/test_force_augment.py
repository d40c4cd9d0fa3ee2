"""Force augmentation and the residual's gain (model/conditioning/force_augment.py, model/denoiser/diffusion.py;
CPU, tiny)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from model.denoiser.config import ModelConfig
from tests.test_model_core import SMALL, write_run

RESIDUAL = ModelConfig(
    **{**SMALL.__dict__, "conditioning": "physics", "physics_depth": "force", "target": "physics_residual"}
)


def _split(tmp_path, n=20, size=32):
    """A run of the 10 mm sphere pressed at (1, -1) mm with Fz 1.0–3.0 N (the first frame without load),
    split 8:2. Its frames are the simulator's renders at the depth each Fz implies and its no-contact
    frame the render without load, so a frame moved to another load can be checked against the render
    at that load."""
    from dataset.split import make_split
    from model.conditioning.force_render import force_pose
    from model.conditioning.physics_condition import split_spec

    pose = np.array([1.0, -1.0, -0.5, 0.0])
    fzs = [0.0] + [1.0 + 2.0 * i / n for i in range(1, n)]
    blank = [(np.zeros((size, size, 3), np.uint8), np.array([0, 0, fz, 0, 0, 0.0]), np.zeros(4), pose) for fz in fzs]
    write_run(tmp_path / "blank.h5", "sphere10mm", blank)
    make_split([tmp_path / "blank.h5"], "8:2", tmp_path / "blank")
    renderer = split_spec(tmp_path / "blank").renderer("sphere10mm")

    def render(fz):
        return renderer.render(force_pose(renderer, pose, fz)[0], np.array([0, 0, fz, 0, 0, 0.0]))

    rows = [(render(fz), w, c, p) for (_, w, c, p), fz in zip(blank, fzs)]
    write_run(tmp_path / "r.h5", "sphere10mm", rows, reference=render(0.0))
    make_split([tmp_path / "r.h5"], "8:2", tmp_path / "split")
    return tmp_path / "split"


def test_the_new_fields_are_checked():
    with pytest.raises(ValueError, match="needs physics_depth force"):
        ModelConfig(**{**RESIDUAL.__dict__, "physics_depth": "pose", "force_augment": 0.25})
    for bad in (-0.1, 0.95, float("nan")):
        with pytest.raises(ValueError, match="force_augment must be a"):
            ModelConfig(**{**RESIDUAL.__dict__, "force_augment": bad})
    for bad in (0.0, -1.0, float("inf"), float("nan"), 5000.0):
        with pytest.raises(ValueError, match="residual_gain must be a number"):
            ModelConfig(**{**RESIDUAL.__dict__, "residual_gain": bad})
    with pytest.raises(ValueError, match="needs target physics_residual"):
        ModelConfig(**{**RESIDUAL.__dict__, "target": "frame", "residual_gain": 8.0})
    assert ModelConfig(**{**RESIDUAL.__dict__, "residual_gain": 8.0, "force_augment": 0.25}).force_augment == 0.25


def test_a_gained_residual_samples_back_differences_past_the_unit_range():
    """At gain 8 a residual of 0.8 (image units) is 3.2 in the target: the samplers clip x̂₀ at ±gain,
    not ±1, so an oracle of the residual gives the frame back, and a zero residual gives the render."""
    import torch

    from model.denoiser.diffusion import Diffusion, from_residual, to_residual

    cfg = ModelConfig(**{**RESIDUAL.__dict__, "residual_gain": 8.0})
    diff = Diffusion(cfg)
    g = torch.Generator().manual_seed(0)
    render = torch.rand(2, 3, 16, 16, generator=g) * 1.0 - 0.9
    clean = (render + 0.8 * torch.rand(2, 3, 16, 16, generator=g)).clamp(-1, 1)
    cond = torch.cat([torch.zeros_like(clean), render], dim=1)
    residual = to_residual(clean, cond, 8.0)
    assert residual.abs().max() > 2.5  # far past the unit range that an unscaled residual keeps to
    assert torch.allclose(from_residual(residual, cond, 8.0), clean, atol=1e-6)
    wrench = torch.zeros(2, 6)

    def oracle(noisy, t, condition, w):
        return residual

    assert diff.loss(oracle, clean, cond, wrench, generator=torch.Generator().manual_seed(0)).item() < 1e-9
    for sampler in ("ddim", "ddpm", "dpm"):
        out = diff.sample(oracle, cond, wrench, steps=10, sampler=sampler, generator=torch.Generator().manual_seed(1))
        assert torch.allclose(out, clean, atol=2e-3), sampler
    zero = diff.sample(lambda x, t, c, w: torch.zeros_like(x), cond, wrench, steps=5, generator=torch.Generator())
    assert torch.allclose(zero, render, atol=1e-6)


def test_a_contact_is_grown_about_its_rendered_centre_by_the_renders_area_ratio():
    """A disc of radius 4 px whose render grows from radius 4 to 6 becomes a disc of radius 6 about the
    same centre; one whose render shrinks to 2 shrinks; a frame whose render shows no contact is unchanged."""
    from model.conditioning.force_augment import contact, grown

    yy, xx = np.mgrid[0:32, 0:32]

    def disc(r, value=60.0, cx=12.0, cy=18.0):
        img = np.full((32, 32, 3), 100.0)
        img[(xx - cx) ** 2 + (yy - cy) ** 2 <= r * r] += value
        return img.astype(np.uint8)

    reference, bare = disc(0), disc(0)
    frame = disc(4, 50.0)
    for r in (6, 2):
        moved = grown(frame, reference, disc(4), disc(r), bare)
        area, cx, cy = contact(moved, reference, 50.0 * 3)
        assert area == pytest.approx(np.pi * r * r, rel=0.25) and (cx, cy) == pytest.approx((12, 18), abs=0.5)
    assert np.array_equal(grown(frame, reference, bare, disc(5), bare), frame)


def test_each_frame_is_shown_again_at_four_loads_grown_as_the_render_grows(tmp_path):
    import torch

    from dataset.torch_dataset import TactileDataset, image_to_tensor
    from model.conditioning.force_augment import ForceAugmented, factors, levels_cache
    from model.conditioning.force_render import force_physics_cache
    from model.conditioning.physics_condition import split_spec

    split = _split(tmp_path)
    spec = split_spec(split)
    own = force_physics_cache(split, "train", 32, spec)
    said: list[str] = []
    path = levels_cache(split, "train", 32, 0.25, spec, log=said.append)
    assert any("Fz × 0.75, 0.875, 1.125, 1.25" in line for line in said)
    levels = np.load(path)
    base = TactileDataset(split, "train", size=32, physics=own)
    aug = ForceAugmented(base, levels, 0.25)
    n = len(base)
    assert len(aug) == 5 * n and levels.shape == (n, 4, 2, 32, 32, 3)
    mean, std = float(base.mean[2]), float(base.std[2])
    loaded, errors = 0, []
    for i in range(n):
        first = base[i]
        assert all(torch.equal(first[k], aug[i][k]) for k in ("tactile", "physics", "wrench", "condition"))
        fz = float(first["wrench"][2]) * std + mean
        for j, factor in enumerate(factors(0.25)):
            item = aug[(1 + j) * n + i]
            assert torch.equal(item["physics"], image_to_tensor(levels[i, j, 0]))
            assert torch.equal(item["tactile"], image_to_tensor(levels[i, j, 1]))
            assert float(item["wrench"][2]) * std + mean == pytest.approx(fz * factor, rel=1e-5, abs=1e-6)
            assert torch.equal(item["wrench"][[0, 1, 3, 4, 5]], first["wrench"][[0, 1, 3, 4, 5]])
            assert torch.equal(item["condition"], first["condition"])
            render, moved = (x.float() for x in (item["physics"], item["tactile"]))
            if fz <= 0:  # no load: every level is the object touching, the frame as it is
                assert torch.equal(item["tactile"], first["tactile"])
                continue
            # the frame (itself a render) moved to Fz' against the render at Fz', and the frame left as it was
            errors.append(
                ((moved - render).abs().mean().item(), (first["tactile"].float() - render).abs().mean().item())
            )
        loaded += fz > 0
    assert loaded >= n - 1
    moved_error, unmoved_error = np.mean(errors, axis=0)
    # scaling keeps the shading inside the contact, where a sphere pressed deeper shows the same normals
    # further out: an approximation, 0.55 of the error of leaving the frame as it was (measured)
    assert moved_error < 0.65 * unmoved_error
    # kept: a second call renders nothing; another span is another cache; a stale array is refused
    said.clear()
    assert levels_cache(split, "train", 32, 0.25, spec, log=said.append) == path and not said
    assert levels_cache(split, "train", 32, 0.1, spec) != path
    with pytest.raises(ValueError, match="stale cache"):
        ForceAugmented(base, levels[:, :3], 0.25)


def test_a_model_trained_with_force_augmentation_records_it_and_generates(tmp_path):
    from model.generation.inference import TrainedModel
    from model.training.build import build
    from model.training.trainer import TrainConfig

    split = _split(tmp_path)
    cfg = ModelConfig(**{**RESIDUAL.__dict__, "image_size": 32, "residual_gain": 4.0, "force_augment": 0.2})
    said: list[str] = []
    trainer = build(
        cfg,
        TrainConfig(steps=2, batch_size=4, checkpoint_every=100, sample_every=0),
        split,
        tmp_path / "m",
        log=said.append,
    )
    assert len(trainer.data) == 5 * 16 and any("force augmentation" in line for line in said)
    trainer.train()
    trainer.save()
    meta = json.loads((tmp_path / "m" / "checkpoint" / "state.json").read_text())
    assert meta["model"]["force_augment"] == 0.2 and meta["model"]["residual_gain"] == 4.0
    model = TrainedModel.load(tmp_path / "m")
    assert model.cfg.residual_gain == 4.0 and model.cfg.force_augment == 0.2
    from objects.indenters import get_indenter

    obj = get_indenter("sphere10mm").object_image(32, 14 / 32)
    frame = model.generate(obj, [0, 0, 2.0, 0, 0, 0], (0.0, 0.0, -0.5, 0.0), steps=2, object_name="sphere10mm")
    assert frame.shape == (32, 32, 3) and frame.dtype == np.uint8
