"""The denoiser and the diffusion maths, on CPU with a tiny configuration."""

import pytest
import torch

from model.denoiser.config import ModelConfig, preset
from model.denoiser.diffusion import Diffusion
from model.denoiser.network import ContactDenoiser, wrench_plane

SMALL = ModelConfig(
    image_size=16, block_out_channels=(16, 32), layers_per_block=1, train_timesteps=100, cond_dropout=0.0
)


def pairs(n=4, size=16, seed=0):
    """Tactile images that depend on the condition: a blob at the object's place, bright with Fz."""
    g = torch.Generator().manual_seed(seed)
    cond = torch.zeros(n, 3, size, size)
    tactile = torch.full((n, 3, size, size), -0.5)
    wrench = torch.randn(n, 6, generator=g)
    for i in range(n):
        r, c = 4 + 3 * (i % 3), 4 + 2 * i % 8
        cond[i, :, r : r + 4, c : c + 4] = 1.0
        tactile[i, 0, r : r + 4, c : c + 4] = torch.tanh(wrench[i, 2])
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
    for bad, words in (
        (wrench[:, :5], "must be \\(batch, 6\\)"),
        (wrench * float("nan"), "NaN"),
        (wrench * 1e6, "absurd"),
    ):
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


def write_run(path, obj, rows, *, kind="rgb", reference=None, profile=None):
    """A complete run file of library object ``obj`` written through RunWriter, one frame per
    row of ``rows``: (frame, wrench, pose_commanded, pose_measured); square frames at 14 mm
    across, background ``reference`` (default black). ``profile``: the sensor profile record it
    keeps (default: the shipped profile's, as a simulated run records it; "": none, a real sensor's)."""
    import numpy as np

    from acquisition.run_file import RunHeader, RunWriter
    from objects.indenters import get_indenter
    from protocols.plan import PHASES
    from sensor_sim.profile import default_profile

    rows = list(rows)
    shape = rows[0][0].shape
    size = shape[0]
    record = default_profile().record() if profile is None else profile
    header = RunHeader(
        "t", "", "", obj, "", kind, 14 / size, 1.0, len(rows), (0, 0, 0, 0), PHASES, sensor_profile=record
    )
    w = RunWriter.create(
        path,
        header,
        shape,
        get_indenter(obj).object_image(size, 14 / size),
        np.zeros(shape, np.uint8) if reference is None else reference,
    )
    for i, (frame, wrench, commanded, measured) in enumerate(rows):
        w.append(
            frame,
            wrench=wrench,
            pose_commanded=commanded,
            pose_measured=measured,
            t_frame_s=float(i),
            t_capture_s=float(i),
            wrench_skew_s=0.0,
            capture_index=i,
            step_index=0,
            phase_index=1,
            level=1,
            retake=0,
        )
    w.set_status("complete")
    w.close()
    return path


def make_split_dir(tmp_path, n=24, size=16, kind="rgb", profile=None):
    """A small real split: run files via RunWriter, split 8:2 (sensor ``kind`` and ``profile``
    recorded, write_run's default: the shipped profile)."""
    import numpy as np

    from dataset.split import make_split

    rng = np.random.default_rng(0)
    rows = (
        (
            rng.integers(0, 256, (size, size, 3), dtype=np.uint8),
            rng.normal(size=6),
            np.zeros(4),
            np.array([0.1 * i, 0, -1, 0]),
        )
        for i in range(n)
    )
    write_run(tmp_path / "r.h5", "sphere10mm", rows, kind=kind, profile=profile)
    make_split([tmp_path / "r.h5"], "8:2", tmp_path / "split")
    return tmp_path / "split"


def test_resume_continues_with_the_same_losses(tmp_path):
    from model.denoiser.checkpoint import CheckpointError
    from model.training.build import build
    from model.training.trainer import TrainConfig

    split = make_split_dir(tmp_path)
    # validation samples every 3 steps in both runs: sampling must not disturb training's state
    cfg = TrainConfig(steps=8, batch_size=4, checkpoint_every=4, seed=3, sample_every=3, samples=2, sample_steps=2)
    straight = build(SMALL, cfg, split, tmp_path / "a", log=lambda m: None).train()
    assert sorted(p.name for p in (tmp_path / "a" / "samples").iterdir()) == ["step-000003.png", "step-000006.png"]
    first = build(SMALL, cfg, split, tmp_path / "b", log=lambda m: None)
    first.train(until=4)  # saves a checkpoint at step 4
    second = build(SMALL, cfg, split, tmp_path / "b", log=lambda m: None)
    second.resume()
    assert second.step == 4
    resumed = second.train()
    assert resumed == pytest.approx(straight, rel=1e-5)  # same data order, noise, optimizer state
    other = ModelConfig(**{**SMALL.__dict__, "block_out_channels": (16, 16)})
    with pytest.raises(CheckpointError, match="different model config"):
        build(other, cfg, split, tmp_path / "b", log=lambda m: None).resume()


def trained_run(tmp_path, steps):
    """A split and a tiny run trained on it for ``steps`` steps, saved: (split dir, run dir)."""
    from model.training.build import build
    from model.training.trainer import TrainConfig

    split = make_split_dir(tmp_path)
    trainer = build(
        SMALL, TrainConfig(steps=steps, batch_size=4, checkpoint_every=100), split, tmp_path / "run", log=lambda m: None
    )
    trainer.train()
    trainer.save()
    return split, tmp_path / "run"


def test_generate_from_a_trained_run(tmp_path):
    import numpy as np

    from model.denoiser.checkpoint import CheckpointError
    from model.generation.inference import TrainedModel

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
    # the checkpoint folder that `train` prints, or a file in it, names the same run (issue 37)
    for given in (run / "checkpoint", run / "checkpoint" / "state.json"):
        again = TrainedModel.load(given)
        assert np.array_equal(again.generate(obj, [0, 0, 2, 0, 0, 0], (0.2, 0.0, 5.0), steps=4, seed=1), a)


def test_evaluate_writes_the_report_with_the_physics_render_row(tmp_path):
    import json

    from model.evaluation.evaluate import evaluate, report

    split, run = trained_run(tmp_path, 2)
    ev = evaluate(run, split, settings=(("ddim", 3), ("ddpm", 4)), limit=3)
    assert [r.setting for r in ev.rows] == ["ddim, 3 steps", "ddpm, 4 steps"] and not ev.markers
    for r in ev.rows + [ev.baseline]:
        assert r.images == 3 and r.mse > 0 and 0 < r.psnr < 60 and -1 <= r.ssim <= 1 and r.seconds_per_image > 0
    # the frames are random noise: the physics render (a smooth gel) is far from them, and it is
    # the simulator's render of each pose, not a copy of the frame
    assert ev.baseline.mse > 1000
    assert set(ev.examples) == {"object at pose", "real", "physics render", "ddim, 3 steps", "ddpm, 4 steps"}
    path = report(ev, tmp_path / "report", title="test")
    text = path.read_text()
    mine, paper = text.split("## The paper's numbers")
    assert "| this model (ddim, 3 steps) | " in mine and "| paper, RGB light | 21.0 |" in paper
    assert "paper, RGB light" not in mine  # the paper's rows in a table of their own (256 px, its data)
    assert (
        "| baseline: physics render at the measured pose (the simulator's mechanics + calibrated lighting, on the "
        "run's no-contact frame) |" in mine
    )
    assert "| baseline: mean training frame |" in mine and "| baseline: nearest training frame by condition |" in mine
    assert str(tmp_path) not in text
    for png in ("error_vs_time.png", "samples.png"):
        assert (tmp_path / "report" / png).stat().st_size > 1000
    assert not (tmp_path / "report" / "marker_flow.png").exists()
    saved = json.loads((tmp_path / "report" / "metrics.json").read_text())
    assert saved["physics_render"]["mse"] == pytest.approx(ev.baseline.mse)


def test_the_report_states_what_was_evaluated_and_labels_its_examples(tmp_path):
    """Image size, model, conditioning, split and machine at the top; each example row with the
    wrench and pose it was generated for; seconds per network evaluation beside per image."""
    from model.evaluation.evaluate import evaluate, report

    split, run = trained_run(tmp_path, 2)
    ev = evaluate(run, split, settings=(("ddim", 4),), limit=3, baseline=False, n_examples=2)
    assert len(ev.example_labels) == 2 and all(
        label.startswith("Fz ") and " mm " in label for label in ev.example_labels
    )
    text = report(ev, tmp_path / "report", title="test").read_text()
    for key in ("image size", "model", "conditioning", "split", "machine"):
        assert f"- **{key}**: " in text, key
    assert "- **image size**: 16×16 px" in text and "by frame, ratios 8:2" in text
    assert "; trained 2 steps × batch " in text  # how far the model was trained
    row = next(line for line in text.splitlines() if line.startswith("| this model (ddim, 4 steps) |"))
    per_image, per_nfe = (float(cell) for cell in row.strip("|").split("|")[-2:])
    assert per_nfe == pytest.approx(per_image / 4, rel=0.01)


def test_physics_render_reproduces_a_simulated_frame(tmp_path):
    """On a frame the simulator made, the baseline differs only by the frame's sensor noise."""
    import numpy as np

    from model.conditioning.baseline import render_frames
    from model.evaluation.metrics import image_metrics
    from objects.pose import Pose
    from sensor_sim.light import OpticsSpec
    from sensor_sim.optics import Renderer
    from sensor_sim.world_contact import rig_contact

    contact = rig_contact("sphere10mm")
    renderer = Renderer(OpticsSpec(kind="rgb", height_px=64, width_px=64, noise_std=1.0), contact.solver.geometry)
    pose = np.array([0.5, -0.3, -0.8, 2.0])
    frame = renderer.render(contact.solve(Pose(*pose), renderer.needs()).fields)
    still = renderer.render({})
    run = _one_frame_run(tmp_path, frame, still, pose)
    (img,), seconds = render_frames([str(run)], np.array([[0, 0]]), pose[None], 64)
    assert image_metrics(frame, img)["mse"] < 3.0 < image_metrics(frame, still)["mse"]
    assert seconds > 0


def _one_frame_run(tmp_path, frame, reference, pose):
    import numpy as np

    return write_run(tmp_path / "one.h5", "sphere10mm", [(frame, np.zeros(6), pose, pose)], reference=reference)


def test_generate_over_a_split_writes_frames_and_an_index(tmp_path):
    import csv

    from model.generation.inference import TrainedModel

    split, run = trained_run(tmp_path, 2)
    n = TrainedModel.load(run).generate_split(split, "test", tmp_path / "gen", steps=2, batch_size=2)
    rows = list(csv.DictReader(open(tmp_path / "gen" / "index.csv")))
    assert n == len(rows) == 5  # 8:2 of 24 frames
    assert all((tmp_path / "gen" / r["png"]).exists() for r in rows)
    assert float(rows[0]["z_mm"]) == pytest.approx(-1.0)


def test_train_command_reads_a_model_toml_and_names_bad_keys(tmp_path):
    import json

    from typer.testing import CliRunner

    from cli.model_app import app

    split = make_split_dir(tmp_path)
    good = tmp_path / "model.toml"
    good.write_text(
        'preset = "tiny"\n[model]\nimage_size = 16\nblock_out_channels = [16, 32]\nconditioning = "plane"\n'
        "train_timesteps = 100\n[train]\nsteps = 3\nbatch_size = 4\nsample_every = 0\n"
    )
    result = CliRunner().invoke(
        app, ["--data", str(split), "--out", str(tmp_path / "run"), "--config", str(good), "--steps", "2"]
    )
    assert result.exit_code == 0, result.output
    meta = json.loads((tmp_path / "run" / "checkpoint" / "state.json").read_text())
    assert meta["step"] == 2  # the command line wins over the file
    assert meta["model"]["image_size"] == 16 and meta["model"]["conditioning"] == "plane"
    assert meta["train"]["batch_size"] == 4
    bad = tmp_path / "bad.toml"
    bad.write_text("[model]\nimage_sise = 64\n")
    result = CliRunner().invoke(app, ["--data", str(split), "--out", str(tmp_path / "x"), "--config", str(bad)])
    assert result.exit_code == 1 and "bad.toml" in result.output and "model.image_sise" in result.output
    bad.write_text('[train]\nsteps = "many"\n')
    result = CliRunner().invoke(app, ["--data", str(split), "--out", str(tmp_path / "x"), "--config", str(bad)])
    assert result.exit_code == 1 and "train.steps" in result.output and "int" in result.output


@pytest.mark.parametrize("prediction", ["epsilon", "v_prediction", "sample"])
def test_loss_targets_and_samplers_agree_for_each_prediction(prediction):
    """An oracle network that knows the clean image answers in the configured target: its
    loss is zero, and every sampler returns the clean image from pure noise."""
    cfg = ModelConfig(**{**SMALL.__dict__, "prediction": prediction})
    diff = Diffusion(cfg)
    clean = torch.rand(2, 3, 16, 16) * 1.6 - 0.8
    ab = diff.alpha_bar

    def oracle(noisy, t, condition, wrench):
        a = ab[t].view(-1, 1, 1, 1)
        eps = (noisy - a.sqrt() * clean) / (1 - a).sqrt()
        return {"epsilon": eps, "v_prediction": a.sqrt() * eps - (1 - a).sqrt() * clean, "sample": clean}[prediction]

    cond, wrench = torch.zeros_like(clean), torch.zeros(2, 6)
    g = torch.Generator().manual_seed(0)
    assert diff.loss(oracle, clean, cond, wrench, generator=g).item() < 1e-6
    for sampler in ("ddim", "dpm", "ddpm"):
        out = diff.sample(oracle, cond, wrench, steps=10, sampler=sampler, generator=torch.Generator().manual_seed(1))
        assert torch.allclose(out, clean, atol=2e-3), sampler
    wrong = "sample" if prediction != "sample" else "epsilon"
    cfg_wrong = ModelConfig(**{**SMALL.__dict__, "prediction": wrong})
    assert (
        Diffusion(cfg_wrong).loss(oracle, clean, cond, wrench, generator=torch.Generator().manual_seed(0)).item() > 1e-2
    )


def test_the_example_model_files_in_docs_load():
    from pathlib import Path

    from model.training.config_file import load_model_file

    files = sorted((Path(__file__).parent.parent / "docs" / "examples").glob("*.toml"))
    assert files
    for path in files:
        cfg, train = load_model_file(path)
        assert cfg.image_size in (64, 128, 256) and train["steps"] > 0


def test_two_processes_train_through_accelerate(tmp_path):
    """`torchrun`/`accelerate launch` runs the same `train`: two CPU processes (gloo) share
    each step's batch; one process logs and saves."""
    import json
    import os
    import signal
    import socket
    import subprocess
    import sys
    from pathlib import Path

    split = make_split_dir(tmp_path, n=40)
    cfg = tmp_path / "m.toml"
    cfg.write_text("[model]\nimage_size = 16\nblock_out_channels = [16, 32]\ntrain_timesteps = 100\n")
    torchrun = Path(sys.executable).with_name("torchrun")
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    with socket.socket() as s:  # a free port for the rendezvous
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    cmd = [
        str(torchrun),
        "--nproc_per_node",
        "2",
        "--master_addr",
        "127.0.0.1",
        "--master_port",
        str(port),
        "-m",
        "cli.model_app",
        "--data",
        str(split),
        "--out",
        str(tmp_path / "run"),
        "--config",
        str(cfg),
        "--steps",
        "4",
        "--batch-size",
        "4",
        "--sample-every",
        "2",
        "--device",
        "cpu",
    ]
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=Path(__file__).parent.parent,
        start_new_session=True,
    )
    try:
        stdout, stderr = proc.communicate(timeout=100)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the workers too, not only torchrun
        proc.communicate()
        raise
    assert proc.returncode == 0, stderr[-2000:]
    assert "x 2 processes" in stdout and stdout.count("checkpoint:") == 1
    meta = json.loads((tmp_path / "run" / "checkpoint" / "state.json").read_text())
    assert meta["step"] == 4 and len(meta["losses"]) == 4
    assert sorted(p.name for p in (tmp_path / "run" / "samples").iterdir()) == ["step-000002.png", "step-000004.png"]


def test_generate_and_evaluate_commands(tmp_path):
    import cv2
    import numpy as np
    from typer.testing import CliRunner

    from cli.model_app import evaluate_app, generate_app

    split, run = trained_run(tmp_path, 2)
    obj = tmp_path / "obj.png"
    cv2.imwrite(str(obj), np.full((40, 40, 3), 200, np.uint8))
    r = CliRunner().invoke(
        generate_app,
        [
            "--checkpoint",
            str(run),
            "--object",
            str(obj),
            "--wrench",
            "0,0,2,0,0,0",
            "--out",
            str(tmp_path / "f.png"),
            "--steps",
            "2",
        ],
    )
    assert r.exit_code == 0, r.output
    assert cv2.imread(str(tmp_path / "f.png")).shape == (16, 16, 3)
    r = CliRunner().invoke(
        generate_app,
        ["--checkpoint", str(run), "--object", str(obj), "--wrench", "0,0,2", "--out", str(tmp_path / "g.png")],
    )
    assert r.exit_code != 0 and "6 comma-separated numbers" in r.output
    r = CliRunner().invoke(generate_app, ["--checkpoint", str(run), "--out", str(tmp_path / "g.png")])
    assert r.exit_code != 0 and "--split" in r.output
    r = CliRunner().invoke(
        generate_app,
        [
            "--checkpoint",
            str(run),
            "--split",
            str(split),
            "--out",
            str(tmp_path / "gen"),
            "--steps",
            "2",
            "--limit",
            "3",
        ],
    )
    assert r.exit_code == 0, r.output
    assert len(list((tmp_path / "gen").glob("*.png"))) == 3
    r = CliRunner().invoke(
        evaluate_app,
        [
            "--checkpoint",
            str(run),
            "--split",
            str(split),
            "--out",
            str(tmp_path / "rep"),
            "--settings",
            "ddim:2",
            "--limit",
            "2",
            "--no-baseline",
        ],
    )
    assert r.exit_code == 0, r.output
    assert (
        "report:" in r.output and "No physics-render row: not asked for" in (tmp_path / "rep" / "report.md").read_text()
    )
    r = CliRunner().invoke(
        evaluate_app,
        ["--checkpoint", str(run), "--split", str(split), "--out", str(tmp_path / "rep"), "--settings", "ddim"],
    )
    assert r.exit_code != 0 and "sampler:steps" in r.output
