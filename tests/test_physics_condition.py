"""Physics conditioning: the simulator's render at each frame's pose as condition channels (CPU, tiny)."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from acquisition import schema as S
from model.denoiser.config import ModelConfig
from objects.pose import Pose
from tests.test_model_core import SMALL, make_split_dir

PHYS = ModelConfig(**{**SMALL.__dict__, "conditioning": "physics+plane"})


def _trained(tmp_path, cfg=PHYS, steps=2):
    from model.training.build import build
    from model.training.trainer import TrainConfig

    tmp_path.mkdir(parents=True, exist_ok=True)
    split = make_split_dir(tmp_path)
    trainer = build(
        cfg,
        TrainConfig(steps=steps, batch_size=4, checkpoint_every=100, sample_every=0),
        split,
        tmp_path / "run",
        log=lambda m: None,
    )
    trainer.train()
    trainer.save()
    return split, tmp_path / "run"


def test_conditioning_names_are_checked_and_combine():
    assert PHYS.uses_physics and PHYS.uses_plane and not PHYS.uses_embedding and PHYS.condition_channels == 6
    cfg = ModelConfig(conditioning="plane+embedding+physics")
    assert cfg.uses_physics and cfg.uses_plane and cfg.uses_embedding
    assert ModelConfig(conditioning="plane").condition_channels == 3
    for bad in ("physic", "plane+plane", "", "plane+", "physics+telepathy"):
        with pytest.raises(ValueError, match="one or more of plane, embedding, physics"):
            ModelConfig(conditioning=bad)


@pytest.fixture(scope="module")
def physics_run(tmp_path_factory):
    """(split, run) of a physics+plane model trained two steps, shared by the tests below."""
    return _trained(tmp_path_factory.mktemp("physics"))


def test_physics_model_records_its_conditioning_and_generates(physics_run):
    import torch

    from model.generation.inference import TrainedModel

    _, run = physics_run
    meta = json.loads((run / "checkpoint" / "state.json").read_text())
    assert meta["model"]["conditioning"] == "physics+plane"
    assert meta["physics"]["sensor_kind"] == "rgb" and meta["physics"]["frame_px"] == 16
    model = TrainedModel.load(run)
    assert model.cfg == PHYS and model.physics is not None and model.physics.mm_per_px == pytest.approx(14 / 16)
    # the network takes 3 noisy + 6 condition + 1 plane channels
    assert model.net.unet.conv_in.in_channels == 10  # type: ignore[union-attr]
    obj = np.zeros((16, 16, 3), np.uint8)
    a = model.generate(obj, [0, 0, 2, 0, 0, 0], (0.2, 0.0, -0.8, 5.0), steps=2, seed=1, object_name="sphere10mm")
    b = model.generate(obj, [0, 0, 2, 0, 0, 0], (0.2, 0.0, -0.8, 5.0), steps=2, seed=1, object_name="sphere10mm")
    assert a.shape == (16, 16, 3) and np.array_equal(a, b)
    # x, y, θ only: the depth where the simulator's contact gives the wrench's Fz
    x, y, z, theta = model.physics_pose("sphere10mm", (0.2, 0.0, 5.0), [0, 0, 2, 0, 0, 0])
    assert (x, y, theta) == (0.2, 0.0, 5.0) and -3.0 < z < 0
    solver = model._physics_renderer("sphere10mm").contact.solver
    assert solver.solve(Pose(x, y, z, theta)).wrench[2] == pytest.approx(2.0, abs=0.01)
    c = model.generate(obj, [0, 0, 2, 0, 0, 0], (0.2, 0.0, 5.0), steps=2, seed=1, object_name="sphere10mm")
    d = model.generate(obj, [0, 0, 2, 0, 0, 0], (0.2, 0.0, z, 5.0), steps=2, seed=1, object_name="sphere10mm")
    assert np.array_equal(c, d)
    with pytest.raises(ValueError, match="needs the depth too"):
        model.physics_pose("sphere10mm", (0.2, 0.0, 5.0))
    with pytest.raises(ValueError, match="beyond what"):
        model.generate(obj, [0, 0, 1e5, 0, 0, 0], (0.2, 0.0, 5.0), steps=2, object_name="sphere10mm")
    with pytest.raises(ValueError, match="Fz must be a finite force"):
        model.generate(obj, [0, 0, -2, 0, 0, 0], (0.2, 0.0, 5.0), steps=2, object_name="sphere10mm")
    with pytest.raises(ValueError, match="library object"):
        model.generate(obj, [0, 0, 2, 0, 0, 0], (0.2, 0.0, -0.8, 5.0), steps=2)
    with pytest.raises(ValueError, match="not one the simulator knows"):
        model.generate(obj, [0, 0, 2, 0, 0, 0], (0, 0, -0.8, 0), steps=2, object_name="teapot")
    with pytest.raises(ValueError, match="finite"):
        model.generate(obj, [0, 0, 2, 0, 0, 0], (0, 0, float("nan"), 0), steps=2, object_name="sphere10mm")
    # a condition without the physics channels is refused by the network, naming the shapes
    with pytest.raises(ValueError, match="6 channels"):
        model.net(
            torch.zeros(1, 3, 16, 16), torch.zeros(1, dtype=torch.long), torch.zeros(1, 3, 16, 16), torch.zeros(1, 6)
        )


def test_physics_model_generates_a_split_as_evaluate_does(physics_run, tmp_path):
    from model.generation.inference import TrainedModel

    split, run = physics_run
    # generate_split (what evaluate uses) renders the physics channels of plain Dataset items
    assert TrainedModel.load(run).generate_split(split, "test", tmp_path / "gen", steps=2, batch_size=2) == 5


def test_generate_command_takes_a_library_object_at_x_y_z_theta(physics_run, tmp_path):
    from typer.testing import CliRunner

    from cli.model_app import generate_app

    _, run = physics_run
    args = ["--checkpoint", str(run), "--wrench", "0,0,2,0,0,0", "--steps", "2", "--out", str(tmp_path / "f.png")]
    r = CliRunner().invoke(generate_app, [*args, "--object", "sphere10mm", "--pose", "0.2,0,-0.8,5"])
    assert r.exit_code == 0 and (tmp_path / "f.png").exists(), r.output
    # a pose without z: the depth from Fz, said; a force the gel cannot give, or a picture instead of an
    # object the simulator knows: one line each
    r = CliRunner().invoke(generate_app, [*args, "--object", "sphere10mm", "--pose", "0.2,0,5", "--size", "32"])
    assert r.exit_code == 0 and "physics render at z -" in r.output and "Fz 2 N" in r.output, r.output
    assert "upsampled from the model's 16x16" in r.output
    bad = [a if a != "0,0,2,0,0,0" else "0,0,-2,0,0,0" for a in args]
    r = CliRunner().invoke(generate_app, [*bad, "--object", "sphere10mm", "--pose", "0.2,0,5"])
    errors = [line for line in r.output.splitlines() if line.startswith("error:")]
    assert r.exit_code == 1 and len(errors) == 1 and "Fz must be" in errors[0] and "Traceback" not in r.output
    r = CliRunner().invoke(generate_app, [*args, "--object", str(tmp_path / "f.png"), "--pose", "0,0,-0.8,0"])
    assert r.exit_code == 1 and "library object name" in r.output


def test_checkpoints_without_physics_still_load_and_a_physics_one_needs_its_record(physics_run, tmp_path):
    import shutil

    from model.denoiser.checkpoint import CheckpointError
    from model.generation.inference import TrainedModel

    _, trained = physics_run
    _, run = _trained(tmp_path / "a", cfg=SMALL, steps=1)
    meta = json.loads((run / "checkpoint" / "state.json").read_text())
    assert "physics" not in meta and meta["model"]["conditioning"] == "plane+embedding"
    assert TrainedModel.load(run).physics is None  # a checkpoint from before physics conditioning
    run = tmp_path / "b"
    shutil.copytree(trained, run)
    state = run / "checkpoint" / "state.json"
    meta = json.loads(state.read_text())
    bad = dict(meta)
    del bad["physics"]
    state.write_text(json.dumps(bad))
    with pytest.raises(CheckpointError, match=r"\[physics\] missing"):
        TrainedModel.load(run)
    state.write_text(json.dumps({**meta, "physics": {**meta["physics"], "mm_per_px": -1}}))
    with pytest.raises(ValueError, match="mm_per_px expected a positive number"):
        TrainedModel.load(run)


def test_a_splits_caches_are_named_in_one_place_and_where_they_always_were(tmp_path):
    """model/conditioning/cache.py names every cache's file; caches written before it are found again."""
    from model.conditioning import cache

    assert cache.folder(tmp_path) == tmp_path / "physics"
    assert cache.pose_renders(tmp_path, "train", 32) == tmp_path / "physics" / "train-32px.npy"
    assert cache.force_renders(tmp_path, "train", 32) == tmp_path / "physics" / "train-32px-fz.npy"
    assert cache.force_levels(tmp_path, "train", 32, 0.25) == tmp_path / "physics" / "train-32px-fz-augment-0.25.npy"


def test_the_cache_is_the_render_and_is_rebuilt_when_stale(tmp_path):
    from dataset.torch_dataset import TactileDataset, uint8_tensor_to_image
    from model.conditioning.baseline import PhysicsRender
    from model.conditioning.physics_condition import physics_cache, resize

    split = make_split_dir(tmp_path)
    lines: list[str] = []
    path = physics_cache(split, "train", 8, log=lines.append)
    assert any("physics channels of 19 train frames" in line for line in lines)
    data = TactileDataset(split, "train", size=8, physics=path)
    render = PhysicsRender(str(data.runs[0]), background="simulator")
    with h5py.File(data.runs[0], "r") as f:
        recorded = f[S.WRENCH][()]
    for i in (0, 7, 18):
        item = data[i]
        expected = resize(render.render(item["pose"].numpy(), recorded[int(item["frame"])]), 8)
        assert np.array_equal(uint8_tensor_to_image(item["physics"]), expected)
    # the frames press harder as i grows (z = -1 throughout, x moves): not all renders are equal
    assert len({data[i]["physics"].numpy().tobytes() for i in range(len(data))}) > 1
    stamp = path.stat().st_mtime_ns
    lines.clear()
    assert physics_cache(split, "train", 8, log=lines.append) == path and not lines  # fresh: kept
    assert path.stat().st_mtime_ns == stamp
    key = json.loads(path.with_suffix(".json").read_text())
    key["runs"][0][1] = "another-run"  # as if the run file had changed
    path.with_suffix(".json").write_text(json.dumps(key))
    physics_cache(split, "train", 8, log=lines.append)
    assert any("stale" in line for line in lines)
    assert json.loads(path.with_suffix(".json").read_text())["runs"][0][1] != "another-run"
    # another part's cache, or another size, is refused by the Dataset in one line
    with pytest.raises(ValueError, match="stale cache"):
        TactileDataset(split, "test", size=8, physics=path)
    with pytest.raises(ValueError, match="stale cache"):
        TactileDataset(split, "train", size=16, physics=path)


def test_physics_is_refused_for_an_object_the_simulator_does_not_know(tmp_path):
    import h5py
    from typer.testing import CliRunner

    from acquisition import attr_checksum
    from cli.model_app import app
    from dataset.split import make_split
    from model.conditioning.physics_condition import PhysicsUnavailable, split_spec

    split = make_split_dir(tmp_path)
    run = json.loads((split / "split.json").read_text())["runs"][0]["path"]
    with h5py.File(run, "r+") as f:  # a run of an object the simulator lacks (written so: checksum and all)
        f.attrs["object_name"] = "my_mug"
        attr_checksum.seal(f)
    make_split([run], "8:2", split)  # the split made again: the file changed since the first
    with pytest.raises(PhysicsUnavailable, match="'my_mug' is not one the simulator knows"):
        split_spec(split)
    result = CliRunner().invoke(
        app,
        ["--data", str(split), "--out", str(tmp_path / "run"), "--conditioning", "physics+embedding", "--steps", "1"],
    )
    assert result.exit_code == 1 and "my_mug" in result.output and "Traceback" not in result.output
    assert [line.startswith("error:") for line in result.output.splitlines()].count(True) == 1
    # without --conditioning the sensor kind's default (physics for rgb) falls back, saying so
    result = CliRunner().invoke(
        app,
        ["--data", str(split), "--out", str(tmp_path / "run"), "--image-size", "16", "--steps", "1"]
        + ["--batch-size", "4", "--sample-every", "0"],
    )
    assert result.exit_code == 0 and "conditioning plane+embedding, not the default" in result.output, result.output
    meta = json.loads((tmp_path / "run" / "checkpoint" / "state.json").read_text())
    assert meta["model"]["conditioning"] == "plane+embedding"


def test_train_picks_the_sensor_kinds_default_and_keeps_every_choice(tmp_path):
    from typer.testing import CliRunner

    from cli.model_app import app
    from model.denoiser.config import DEFAULT_CONDITIONING, DEFAULT_TARGET

    split = make_split_dir(tmp_path)
    common = ["--data", str(split), "--image-size", "16", "--steps", "1", "--batch-size", "4", "--sample-every", "0"]
    r = CliRunner().invoke(app, [*common, "--out", str(tmp_path / "a")])
    assert r.exit_code == 0, r.output
    meta = json.loads((tmp_path / "a" / "checkpoint" / "state.json").read_text())
    assert meta["model"]["conditioning"] == DEFAULT_CONDITIONING["rgb"]
    assert meta["model"]["target"] == "frame"  # rgb: the residual was not measured
    r = CliRunner().invoke(app, [*common, "--out", str(tmp_path / "b"), "--conditioning", "plane"])
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "b" / "checkpoint" / "state.json").read_text())["model"]["conditioning"] == "plane"
    # a marker sensor: its conditioning and the residual target by default; a given target wins
    (tmp_path / "m").mkdir()
    markers = make_split_dir(tmp_path / "m", size=32, kind="rgb_markers")
    mcommon = [*common[:1], str(markers), *common[2:]]
    r = CliRunner().invoke(app, [*mcommon, "--out", str(tmp_path / "c")])
    assert r.exit_code == 0 and "target physics_residual" in r.output, r.output
    model = json.loads((tmp_path / "c" / "checkpoint" / "state.json").read_text())["model"]
    assert (model["conditioning"], model["target"]) == (
        DEFAULT_CONDITIONING["rgb_markers"],
        DEFAULT_TARGET["rgb_markers"],
    )
    r = CliRunner().invoke(app, [*mcommon, "--out", str(tmp_path / "d"), "--target", "frame"])
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "d" / "checkpoint" / "state.json").read_text())["model"]["target"] == "frame"


def test_physics_residual_target_denoises_the_difference_from_the_render():
    """With target physics_residual, an oracle that knows the frame's difference from the physics
    channels has zero loss, every sampler gives back the frame, and a network that answers zero
    (nothing to correct) samples the physics render itself; the target needs physics conditioning."""
    import torch

    from model.denoiser.diffusion import Diffusion, from_residual, to_residual

    with pytest.raises(ValueError, match="physics_residual needs physics conditioning"):
        ModelConfig(**{**SMALL.__dict__, "conditioning": "plane", "target": "physics_residual"})
    with pytest.raises(ValueError, match="target must be one of"):
        ModelConfig(**{**SMALL.__dict__, "target": "image"})
    cfg = ModelConfig(**{**SMALL.__dict__, "conditioning": "physics+plane", "target": "physics_residual"})
    diff = Diffusion(cfg)
    g = torch.Generator().manual_seed(0)
    clean = torch.rand(2, 3, 16, 16, generator=g) * 1.6 - 0.8
    render = (clean + 0.2 * torch.randn(2, 3, 16, 16, generator=g)).clamp(-1, 1)
    cond = torch.cat([torch.zeros_like(clean), render], dim=1)  # object image, then the physics channels
    wrench = torch.zeros(2, 6)
    residual = to_residual(clean, cond)
    assert torch.allclose(from_residual(residual, cond), clean, atol=1e-6)

    def oracle(noisy, t, condition, w):  # prediction "sample": the clean residual
        return residual

    assert diff.loss(oracle, clean, cond, wrench, generator=torch.Generator().manual_seed(0)).item() < 1e-9
    for sampler in ("ddim", "dpm"):
        out = diff.sample(oracle, cond, wrench, steps=10, sampler=sampler, generator=torch.Generator().manual_seed(1))
        assert torch.allclose(out, clean, atol=2e-3), sampler
    zero = diff.sample(lambda x, t, c, w: torch.zeros_like(x), cond, wrench, steps=5, generator=torch.Generator())
    assert torch.allclose(zero, render, atol=1e-6)
    # the frame target (the paper's) on the same oracle is not at zero: the target is what changed
    plain = Diffusion(ModelConfig(**{**SMALL.__dict__, "conditioning": "physics+plane"}))
    assert plain.loss(oracle, clean, cond, wrench, generator=torch.Generator().manual_seed(0)).item() > 1e-2


def test_a_swept_fz_is_rendered_at_the_depth_that_gives_it(tmp_path):
    """evaluate's force sweep marks items whose Fz it changed: their physics channels are rendered
    at the depth where the simulator's contact gives that Fz, so a harder press is a deeper render."""
    from dataset.torch_dataset import TactileDataset, uint8_tensor_to_image
    from model.conditioning.baseline import PhysicsRender
    from model.conditioning.physics_condition import resize, split_spec
    from model.generation.inference import add_physics
    from sensor_sim.load_match import depth_for_force

    split = make_split_dir(tmp_path, n=24, size=32)
    data = TactileDataset(split, "train", size=32)
    render = PhysicsRender(str(data.runs[0]), background="simulator")
    x, y, _, theta = (float(v) for v in data[3]["pose"].numpy())
    images = []
    for fz in (1.0, 6.0):
        it = data[3]
        it["wrench_raw"] = np.array([0.0, 0.0, fz, 0.0, 0.0, 0.0])
        it["depth_from_fz"] = True
        add_physics([it], 32, split_spec(split))
        depth = depth_for_force(render.contact.solver, x, y, theta, fz)
        expected = resize(render.render(np.array([x, y, -depth, theta]), it["wrench_raw"]), 32)
        assert np.array_equal(uint8_tensor_to_image(it["physics"]), expected)
        images.append(expected.astype(float))
    assert np.abs(images[1] - images[0]).mean() > 0.5  # the harder press shows
