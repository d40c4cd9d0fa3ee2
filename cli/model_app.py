"""``train``, ``generate`` and ``evaluate``: the contact-condition-guided diffusion model."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

app = typer.Typer(add_completion=False)

Threads = Annotated[
    Optional[int],
    typer.Option(
        help="torch CPU threads (default: one per core not busy with other processes, model/threads.py; or the "
        "TACTILE_TORCH_THREADS environment variable).",
        min=1,
        max=256,
    ),
]


def one_line_errors(fn):
    """Expected failures (bad files, values, checkpoints, splits) become one red line and exit 1."""
    import functools

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from cli.one_line import passes_through, unexpected
        from common.errors import ToolError
        from model.checkpoint import CheckpointError

        try:
            return fn(*args, **kwargs)
        except (ToolError, CheckpointError, ValueError, KeyError, OSError) as exc:
            message = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        except Exception as exc:  # nothing expected it: still one line, naming its type (cli/one_line.py)
            if passes_through(exc):
                raise
            message = unexpected(exc, "model")
        typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
        raise typer.Exit(1)

    return wrapper


@app.command()
@one_line_errors
def train(
    data: Annotated[Path, typer.Option(help="A split directory from `dataset split` (split.json + index files).")],
    out: Annotated[
        Path,
        typer.Option(help="Run directory: checkpoint/ (safetensors) and samples/ (validation PNGs) are written here."),
    ],
    config: Annotated[
        Optional[Path],
        typer.Option(
            help="A model TOML: preset, \\[model] and \\[train] tables (docs/model.md). Options given here win. "
            "Default: none (the preset)."
        ),
    ] = None,
    preset: Annotated[
        Optional[str],
        typer.Option(help="Model size: tiny (CPU, 32 px) or paper (GPU, 256 px). Default: the config's, else tiny."),
    ] = None,
    image_size: Annotated[Optional[int], typer.Option(help="Image side in px (default: the preset's).", min=8)] = None,
    conditioning: Annotated[
        Optional[str],
        typer.Option(
            help="Condition components joined by +: plane (the paper's H(F)), embedding (a learned wrench "
            "embedding), physics (the simulator's render at each frame's measured pose; library objects only), e.g. "
            "plane+embedding or physics+plane+embedding. Default: the config's, else the measured best for the "
            "split's sensor kind (docs/model.md)."
        ),
    ] = None,
    prediction: Annotated[
        Optional[str],
        typer.Option(
            help="Network target: sample (y0), epsilon (the paper's) or v_prediction (default: the preset's, sample)."
        ),
    ] = None,
    target: Annotated[
        Optional[str],
        typer.Option(
            help="What is denoised: frame (the paper's) or physics_residual (the frame minus the physics render; "
            "needs physics conditioning). Default: the config's, else frame."
        ),
    ] = None,
    physics_depth: Annotated[
        Optional[str],
        typer.Option(
            help="Where physics conditioning renders each frame: pose (at its measured z) or force (at the depth "
            "where the simulator's contact gives its measured Fz, so the force shapes the picture; docs/model.md). "
            "Default: the config's, else pose."
        ),
    ] = None,
    residual_gain: Annotated[
        Optional[float],
        typer.Option(
            help="With target physics_residual: multiply the residual by this before it is noised (a real sensor's "
            "residual is a few grey levels, which the noise drowns at gain 1; docs/model.md). Default: the config's, "
            "else 1.",
            min=0.0,
        ),
    ] = None,
    force_augment: Annotated[
        Optional[float],
        typer.Option(
            help="With physics depth force: also train on each frame at Fz x (1 +- S, 1 +- S/2), its render at that "
            "load and its contact grown or shrunk as the render's (an assumption; docs/model.md). 0: off (default).",
            min=0.0,
        ),
    ] = None,
    steps: Annotated[Optional[int], typer.Option(help="Optimisation steps in all (default 2000).", min=1)] = None,
    batch_size: Annotated[
        Optional[int], typer.Option(help="Images per step, over all GPUs (default 16).", min=1)
    ] = None,
    lr: Annotated[
        Optional[float],
        typer.Option(help="Adam learning rate (default: the preset's, 1e-3 tiny, 2e-4 paper).", min=0.0),
    ] = None,
    checkpoint_every: Annotated[
        Optional[int], typer.Option(help="Steps between checkpoints (default 500).", min=1)
    ] = None,
    sample_every: Annotated[
        Optional[int], typer.Option(help="Steps between validation sample PNGs; 0: never (default 500).", min=0)
    ] = None,
    seed: Annotated[
        Optional[int], typer.Option(help="Seed of the weights, the data order and the noise (default 0).")
    ] = None,
    mixed_precision: Annotated[
        Optional[str], typer.Option(help="auto (bf16/fp16 on CUDA, none on CPU), no, fp16 or bf16 (default auto).")
    ] = None,
    resume: Annotated[bool, typer.Option(help="Continue from OUT/checkpoint exactly where it stopped.")] = False,
    device: Annotated[
        Optional[str],
        typer.Option(help="cpu or cuda (default: cuda when available; under `accelerate launch`, each process's GPU)."),
    ] = None,
    profile: Annotated[
        Optional[Path],
        typer.Option(
            help="Sensor profile TOML of the physics conditioning (`rig sensor calibrate` writes one), for every run. "
            "Default: the profile each run records; a run that records none is refused for physics conditioning "
            "(never rendered through another sensor's profile).",
            dir_okay=False,
        ),
    ] = None,
    override_profile: Annotated[
        bool,
        typer.Option(
            "--override-profile",
            help="Render runs that record another sensor profile than --profile through --profile anyway. Default: "
            "such a run is refused, naming both profiles.",
        ),
    ] = False,
    threads: Threads = None,
):
    """Train the denoiser; progress shows the loss and images/s; checkpoints are safetensors.

    Several GPUs: `accelerate launch -m cli.model_app --data ... --out ...` runs this same command.
    """
    import dataclasses

    from model.build import build
    from model.config import PRESET_TRAINING
    from model.config import preset as make_preset
    from model.config_file import load_model_file
    from model.force_augment import factors
    from model.threads import set_threads
    from model.trainer import TrainConfig
    from sensor_sim.profile import load_profile

    sensor = load_profile(profile) if profile is not None else None  # a bad file: ProfileError, one line
    if config is not None:
        model_cfg, train_fields = load_model_file(config, preset)
    else:
        model_cfg, train_fields = make_preset(preset or "tiny"), dict(PRESET_TRAINING.get(preset or "tiny", {}))
    model_over = {
        k: v
        for k, v in (
            ("image_size", image_size),
            ("conditioning", conditioning),
            ("prediction", prediction),
            ("target", target),
            ("physics_depth", physics_depth),
            ("residual_gain", residual_gain),
            ("force_augment", force_augment),
        )
        if v is not None
    }
    if conditioning is None and not _names_conditioning(config):
        model_over["conditioning"], best_target = _default_conditioning(data, sensor, override_profile)
        if target is None and not _names_key(config, "target"):
            model_over["target"] = best_target
    if model_over:
        model_cfg = dataclasses.replace(model_cfg, **model_over)
    given = {
        "steps": steps,
        "batch_size": batch_size,
        "lr": lr,
        "checkpoint_every": checkpoint_every,
        "sample_every": sample_every,
        "seed": seed,
        "mixed_precision": mixed_precision,
    }
    cfg = TrainConfig(**{**train_fields, **{k: v for k, v in given.items() if v is not None}})
    threads_line = set_threads(threads)  # before anything runs; said once the run is set up (one-line errors)
    trainer = build(
        model_cfg, cfg, data, out, device=device, log=typer.echo, profile=sensor, override_profile=override_profile
    )
    say = typer.echo if trainer.is_main else (lambda line: None)
    say(threads_line)
    if resume:
        trainer.resume()
        say(f"resumed at step {trainer.step}")
    say(
        f"model: {model_cfg.network}, {model_cfg.image_size} px, widths {list(model_cfg.block_out_channels)}, "
        f"{model_cfg.conditioning}"
        + ("; physics at the depth Fz implies" if model_cfg.force_depth else "")
        + ("; target physics_residual" if model_cfg.residual else "")
        + (f" x {model_cfg.residual_gain:g}" if model_cfg.residual_gain != 1 else "")
        + f"; {len(trainer.data)} training "
        + (
            f"items (frames at {1 + len(factors(model_cfg.force_augment))} loads each, "
            f"force_augment {model_cfg.force_augment:g})"
            if model_cfg.force_augment
            else "frames"
        )
        + f"; device {trainer.device}"
        + (f" x {trainer.acc.num_processes} processes" if trainer.acc.num_processes > 1 else "")
    )
    trainer.train()
    if trainer.acc.num_processes > 1:  # every process says what it read: its own shard of each epoch
        typer.echo(
            f"process {trainer.acc.process_index} of {trainer.acc.num_processes}: read {len(trainer.read)} of "
            f"{len(trainer.data)} training items (its share of each step's batch)"
        )
    say(f"checkpoint: {trainer.save()}")


def _names_conditioning(config: Path | None) -> bool:
    """Whether a model TOML sets [model] conditioning (then it wins over the per-sensor default)."""
    return _names_key(config, "conditioning")


def _names_key(config: Path | None, key: str) -> bool:
    """Whether a model TOML sets [model] ``key``."""
    import tomllib

    if config is None:
        return False
    try:
        return key in tomllib.loads(config.read_text()).get("model", {})
    except (OSError, tomllib.TOMLDecodeError, AttributeError):
        return False  # load_model_file reports the bad file in one line


def _default_conditioning(split: Path, profile=None, override_profile: bool = False) -> tuple[str, str]:
    """The measured best conditioning and target for the split's sensor kind (model/config.py);
    plane+embedding and the frame, said in a line, where the best is physics and the simulator
    cannot render the split's runs (an object it does not know, a run without a sensor profile
    and no --profile)."""
    from dataset.split import check_unchanged, load_split
    from model.config import ModelConfig, default_conditioning, default_target
    from model.physics_condition import PhysicsUnavailable, split_spec

    manifest, _ = load_split(split)
    check_unchanged(manifest, split)  # the sensor kind read back from the run files, never split.json's word alone
    kinds = {str(r.get("sensor", "")) for r in manifest["runs"]}
    kind = kinds.pop() if len(kinds) == 1 else ""
    best = default_conditioning(kind)
    if ModelConfig(conditioning=best).uses_physics:
        try:
            split_spec(split, profile, override=override_profile)
        except PhysicsUnavailable as exc:
            typer.echo(f"conditioning plane+embedding, not the default {best}: {exc}")
            return "plane+embedding", "frame"
    return best, default_target(kind, best)


generate_app = typer.Typer(add_completion=False)


def _numbers(text: str, n: int, what: str, limits: list[tuple[float, str]]) -> list[float]:
    """``n`` finite comma-separated numbers, each within ±its limit (``limits``: (bound, unit) per value)."""
    import math

    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise typer.BadParameter(f"{what}: expected {n} comma-separated numbers, got {text!r}") from None
    if len(values) != n:
        raise typer.BadParameter(f"{what}: expected {n} comma-separated numbers, got {len(values)} in {text!r}")
    for k, (v, (bound, unit)) in enumerate(zip(values, limits)):
        if not math.isfinite(v) or abs(v) > bound:
            raise typer.BadParameter(
                f"{what}: value {k + 1} is {v:g}; expected a finite number within ±{bound:g} {unit}"
            )
    return values


@generate_app.command()
@one_line_errors
def generate(
    checkpoint: Annotated[
        Path, typer.Option(help="A run directory written by `train --out DIR`: DIR, or DIR/checkpoint as train prints.")
    ],
    out: Annotated[Path, typer.Option(help="The generated frame (PNG); with --split, a folder of PNGs.")],
    object_image: Annotated[
        Optional[str],
        typer.Option(
            "--object",
            help=(
                "The object: a PNG/JPEG of its contact face spanning the sensor's field of view, a library object name "
                "(e.g. sphere10mm) or a run file (.h5, its object image); needed unless --split (default: none)."
            ),
        ),
    ] = None,
    wrench: Annotated[
        Optional[str], typer.Option(help="Fx,Fy,Fz (N),Mx,My,Mz (N·mm); needed unless --split (default: none).")
    ] = None,
    pose: Annotated[
        str,
        typer.Option(
            help="x,y (mm),theta (deg) of the object on the sensor, or x,y,z (mm),theta with z the depth from the "
            "contact point (negative into the gel). A physics-conditioned model given x,y,theta renders at the depth "
            "where the simulator's contact gives the wrench's Fz, and says which."
        ),
    ] = "0,0,0",
    split: Annotated[
        Optional[Path],
        typer.Option(
            help="Instead of --object/--wrench: generate every frame of a split's part (conditions from its runs). "
            "Default: none."
        ),
    ] = None,
    part: Annotated[str, typer.Option(help="With --split: the part to generate (train, val or test).")] = "test",
    limit: Annotated[
        Optional[int], typer.Option(help="With --split: at most this many frames, spread evenly (default: all).", min=1)
    ] = None,
    steps: Annotated[int, typer.Option(help="Sampler steps.", min=1, max=1000)] = 50,
    sampler: Annotated[str, typer.Option(help="ddim, ddpm or dpm.")] = "ddim",
    guidance: Annotated[float, typer.Option(help="Classifier-free guidance weight (1: none).", min=0.0)] = 1.0,
    seed: Annotated[int, typer.Option(help="Noise seed: the same seed gives the same frames.")] = 0,
    size: Annotated[
        Optional[int],
        typer.Option(
            help="Write the frame at this many pixels square (default: the model's own size; larger is upsampled, and "
            "says so).",
            min=8,
            max=4096,
        ),
    ] = None,
    device: Annotated[Optional[str], typer.Option(help="cpu or cuda (default: cuda when available).")] = None,
    threads: Threads = None,
):
    """Generate a tactile frame for an object, a wrench and a pose, or every frame of a split."""
    import cv2
    import numpy as np

    from model.inference import TrainedModel
    from model.threads import set_threads

    set_threads(threads)  # the output stays the frame's line (or one error line)
    if split is None:  # the options checked before the model loads
        from dataset.import_checks import FORCE_N, POSE_LIMIT, TORQUE_NMM

        if object_image is None or wrench is None:
            raise typer.BadParameter("give --object and --wrench, or --split")
        w = _numbers(wrench, 6, "--wrench", [(FORCE_N, "N")] * 3 + [(TORQUE_NMM, "N·mm")] * 3)
        four = pose.count(",") == 3
        p = _numbers(
            pose, 4 if four else 3, "--pose", [(POSE_LIMIT, "mm")] * (3 if four else 2) + [(POSE_LIMIT, "deg")]
        )
    model = TrainedModel.load(checkpoint, _device(device))
    if split is not None:
        written = model.generate_split(
            split, part, out, limit=limit, steps=steps, sampler=sampler, seed=seed, guidance=guidance, log=typer.echo
        )
        typer.echo(f"{out}: {written} frames (PNG, named RUN-FRAME.png) and index.csv")
        return
    assert object_image is not None  # checked above
    img = _object_image(object_image, model.frame_px, model.mm_per_px)
    frame = model.generate(
        img,
        np.asarray(w),
        p,
        steps=steps,
        sampler=sampler,
        seed=seed,
        guidance=guidance,
        object_name=_object_name(object_image) if model.cfg.uses_physics else None,
    )
    native = frame.shape[0]
    note = f"the model's own size, {native}x{native}"
    if size is not None and size != native:
        frame = cv2.resize(frame, (size, size), interpolation=cv2.INTER_CUBIC if size > native else cv2.INTER_AREA)
        note = f"{'upsampled' if size > native else 'downsampled'} from the model's {native}x{native}"
    if model.cfg.uses_physics and (len(p) == 3 or model.cfg.force_depth):
        z = model.physics_pose(_object_name(object_image), p, np.asarray(w))[2]
        note += f"; physics render at z {z:+.3f} mm, where the contact gives Fz {w[2]:g} N"
        if len(p) == 4:
            note += " (this model renders at the depth Fz implies: the z given is not used)"
    _write_png(out, frame)
    typer.echo(f"{out}: {frame.shape[1]}x{frame.shape[0]} ({note})")


def _device(device: str | None) -> str:
    import torch

    if device is None:
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device.split(":")[0] not in ("cpu", "cuda"):
        raise ValueError(f"--device: expected cpu or cuda, got {device!r}")
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise ValueError("--device cuda: no CUDA device is available here")
    return device


def _object_image(source: str, frame_px: int, mm_per_px: float):
    """The object image for --object: a picture file, a run file's object image, or a library object drawn at
    the training frames' scale."""
    import cv2

    path = Path(source)
    if path.suffix.lower() in (".h5", ".hdf5"):
        from acquisition import schema as S
        from acquisition.run_reader import RunReader

        with RunReader.open(path) as f:
            return f.image(S.OBJECT_IMAGE)
    if path.suffix:
        img = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if img is None:
            raise ValueError(f"--object {path}: cannot read it as an image")
        return img
    from objects.indenters import INDENTERS, get_indenter

    if source not in INDENTERS:
        raise ValueError(
            f"--object {source!r}: not an image or run file, nor a library object ({', '.join(INDENTERS)})"
        )
    return get_indenter(source).object_image(frame_px, mm_per_px)


def _object_name(source: str) -> str:
    """The library object --object names (itself, or a run file's object) for the physics render."""
    path = Path(source)
    if path.suffix.lower() in (".h5", ".hdf5"):
        from acquisition import schema as S
        from acquisition.run_reader import RunReader

        with RunReader.open(path) as f:
            return f.text(S.ATTR_OBJECT)
    if path.suffix:
        raise ValueError(
            f"--object {path}: this model is conditioned on the physics render; give a library object name or a "
            "run file of one (the simulator needs the object's shape, not its picture)"
        )
    return source


def _write_png(path: Path, image) -> None:
    """Write an image, creating its folder; a failed write is an error, never a silent success."""
    import cv2

    if path.suffix.lower() not in (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"):
        raise ValueError(f"--out {path}: expected an image file name ending in .png")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"--out {path}: cannot create its folder ({exc.strerror})") from None
    if not cv2.imwrite(str(path), image):
        raise ValueError(f"--out {path}: could not write the image")


evaluate_app = typer.Typer(add_completion=False)


@evaluate_app.command()
@one_line_errors
def evaluate(
    checkpoint: Annotated[
        Path, typer.Option(help="A run directory written by `train --out DIR`: DIR, or DIR/checkpoint as train prints.")
    ],
    split: Annotated[
        Path,
        typer.Option(help="The split directory; its test parts are evaluated (test, and test_object if it has one)."),
    ],
    out: Annotated[Path, typer.Option(help="Folder for report.md, metrics.json and the figures (PNG).")],
    settings: Annotated[
        str,
        typer.Option(
            help="Sampler settings as sampler:steps, comma-separated (ddim, ddpm, dpm); each is a row and a "
            "point on the error-against-run-time plot."
        ),
    ] = "ddim:10,ddim:25,ddim:50",
    part: Annotated[
        Optional[str],
        typer.Option(
            help="The split part to evaluate (default: every test part the split has: test, and test_object, "
            "the objects held out of training by `dataset split --hold-out`), each a section of one report."
        ),
    ] = None,
    limit: Annotated[
        Optional[int],
        typer.Option(help="At most this many frames of each part, spread evenly over it (default: all).", min=1),
    ] = None,
    force_sweep: Annotated[
        bool,
        typer.Option(
            help="The force-response check: at a few test poses, sweep Fz, Fx, Fy and Mz over their training "
            "range and measure the generated contact's area, centroid and shading against real frames at "
            "matching force (or the physics render); generated with the first --settings entry."
        ),
    ] = True,
    sweep_poses: Annotated[
        int,
        typer.Option(help="Poses of each part the force sweep is made at, spread over the field and the loads.", min=1),
    ] = 8,
    sweep_points: Annotated[int, typer.Option(help="Values of each wrench component per sweep.", min=2)] = 7,
    sweep_beyond: Annotated[
        float,
        typer.Option(
            help="Fz is also swept at two values up to this share of its training range past the training maximum "
            "(how the model degrades where it was never trained; 0: not).",
            min=0.0,
            max=10.0,
        ),
    ] = 1.0,
    markers: Annotated[
        Optional[bool],
        typer.Option(
            "--markers/--no-markers", help="Marker displacement error (default: when the sensor has markers)."
        ),
    ] = None,
    baseline: Annotated[
        bool, typer.Option(help="The physics-render row: the simulator's render of each frame at its measured pose.")
    ] = True,
    batch_size: Annotated[int, typer.Option(help="Frames generated at once (memory).", min=1)] = 64,
    seed: Annotated[int, typer.Option(help="Noise seed.")] = 0,
    device: Annotated[Optional[str], typer.Option(help="cpu or cuda (default: cuda when available).")] = None,
    profile: Annotated[
        Optional[Path],
        typer.Option(
            help="Sensor profile TOML for the physics-render row (`rig sensor calibrate` writes one). Default: the "
            "profile each run file records (found again by its content hash); a run that records none is refused "
            "(give this, or --no-baseline): its sensor is never guessed.",
            dir_okay=False,
        ),
    ] = None,
    threads: Threads = None,
):
    """MSE, MAE, SSIM, PSNR (and marker error) per sampler setting against seconds per image, beside the
    physics render and the paper's table."""
    import torch

    from model.checkpoint import run_folder
    from model.evaluate import SweepOptions, evaluate_parts, report
    from model.threads import set_threads

    set_threads(threads)  # the report's context states the count
    try:
        pairs = [(s.split(":")[0], int(s.split(":")[1])) for s in settings.split(",")]
    except (IndexError, ValueError):
        raise typer.BadParameter(f"--settings: expected sampler:steps[,sampler:steps...], got {settings!r}") from None
    if any(steps < 1 for _, steps in pairs):
        raise typer.BadParameter(f"--settings {settings!r}: every step count must be at least 1")
    sweep = (
        SweepOptions(sweep_poses, sweep_points, pairs[0][0], pairs[0][1], beyond=sweep_beyond) if force_sweep else None
    )
    evs = evaluate_parts(
        checkpoint,
        split,
        parts=[part] if part else None,
        settings=pairs,
        limit=limit,
        markers=markers,
        baseline=baseline,
        seed=seed,
        batch_size=batch_size,
        device=device or ("cuda" if torch.cuda.is_available() else "cpu"),
        log=typer.echo,
        profile=profile,
        sweep=sweep,
    )
    for ev in evs:
        for r in ev.rows + ([ev.baseline] if ev.baseline else []):
            mk = "" if r.marker_px is None else f"  markers {r.marker_px:.2f} px"
            typer.echo(
                f"{ev.part:>11} {r.setting:>16}: MSE {r.mse:7.2f}  MAE {r.mae:5.2f}  SSIM {r.ssim:.3f}  "
                f"PSNR {r.psnr:5.2f}{mk}  {r.seconds_per_image:.4f} s/image"
            )
    parts = ", ".join(ev.part for ev in evs)
    title = (
        f"Evaluation of {run_folder(checkpoint).resolve().name} on {split.resolve().name} ({parts})"  # names, not paths
    )
    typer.echo(f"report: {report(evs, out, title=title)}")


compare_app = typer.Typer(add_completion=False)


@compare_app.command()
@one_line_errors
def compare(
    data: Annotated[Path, typer.Option(help="A split directory from `dataset split`.")],
    out: Annotated[
        Path,
        typer.Option(help="Folder for compare.md, compare.json and each run (CANDIDATE/seed-S with its report)."),
    ],
    candidate: Annotated[
        list[str],
        typer.Option(
            help="A setting to compare, repeated: a conditioning, then key=value of model fields, e.g. plane, physics, "
            "physics,physics_depth=force,target=physics_residual."
        ),
    ],
    seeds: Annotated[str, typer.Option(help="Training seeds, comma-separated (at least 2 for a spread).")] = "0,1,2",
    config: Annotated[
        Optional[Path], typer.Option(help="A model TOML every candidate starts from (default: the preset).")
    ] = None,
    preset: Annotated[Optional[str], typer.Option(help="tiny or paper (default: the config's, else tiny).")] = None,
    image_size: Annotated[Optional[int], typer.Option(help="Image side in px (default: the preset's).", min=8)] = None,
    steps: Annotated[
        Optional[str],
        typer.Option(
            help="Training steps of every run (default 2000); several, comma-separated (400,1200): each candidate "
            "at each, a setting of its own named 'CANDIDATE @ N steps'."
        ),
    ] = None,
    batch_size: Annotated[Optional[int], typer.Option(help="Images per step (default 16).", min=1)] = None,
    lr: Annotated[Optional[float], typer.Option(help="Adam learning rate (default: the preset's).", min=0.0)] = None,
    settings: Annotated[
        str, typer.Option(help="Sampler settings of the evaluation, sampler:steps, comma-separated.")
    ] = "ddim:10",
    limit: Annotated[
        Optional[int], typer.Option(help="At most this many frames of each part (default: all).", min=1)
    ] = None,
    sweep_poses: Annotated[
        int,
        typer.Option(help="Poses of each part the force sweep is made at, spread over the field and the loads.", min=1),
    ] = 8,
    sweep_points: Annotated[int, typer.Option(help="Values of each wrench component per sweep.", min=2)] = 7,
    profile: Annotated[
        Optional[Path],
        typer.Option(
            help="Sensor profile TOML for runs that record none (physics conditioning and the physics row); "
            "default: each run's recorded one.",
            dir_okay=False,
        ),
    ] = None,
    report_only: Annotated[
        bool,
        typer.Option(
            "--report-only",
            help="Write compare.md again from the runs' saved evaluations (OUT/CANDIDATE/seed-S/report/"
            "metrics.json); nothing is trained or evaluated, and a missing run is named.",
        ),
    ] = False,
    threads: Threads = None,
):
    """Train every candidate setting with each seed on one split, evaluate each alike, and report per test part
    the mean ± spread over seeds beside the baselines; a setting leads only where the difference exceeds the
    spread."""
    import dataclasses
    import os

    from common.machine import describe
    from model.compare import Candidate, saved_results, summary
    from model.compare import compare as run_compare
    from model.compare_report import write_compare_report
    from model.config import PRESET_TRAINING
    from model.config import preset as make_preset
    from model.config_file import load_model_file
    from model.evaluate import SweepOptions
    from model.threads import set_threads
    from sensor_sim.profile import load_profile

    threads_line = set_threads(threads)
    cands = [Candidate.parse(c) for c in candidate]
    step_list = _step_counts(steps)
    if len(step_list) > 1:
        cands = [c.with_steps(n) for c in cands for n in step_list]
    try:
        seed_list = [int(s) for s in seeds.split(",") if s.strip()]
    except ValueError:
        raise typer.BadParameter(f"--seeds: expected whole numbers separated by commas, got {seeds!r}") from None
    try:
        pairs = [(s.split(":")[0], int(s.split(":")[1])) for s in settings.split(",")]
    except (IndexError, ValueError):
        raise typer.BadParameter(f"--settings: expected sampler:steps[,sampler:steps...], got {settings!r}") from None
    if config is not None:
        base, train_fields = load_model_file(config, preset)
    else:
        base, train_fields = make_preset(preset or "tiny"), dict(PRESET_TRAINING.get(preset or "tiny", {}))
    if image_size is not None:
        base = dataclasses.replace(base, image_size=image_size)
    given = {"steps": step_list[0] if step_list else None, "batch_size": batch_size, "lr": lr}
    train_fields = {**train_fields, "sample_every": 0, **{k: v for k, v in given.items() if v is not None}}
    train_fields.setdefault("checkpoint_every", train_fields.get("steps", 2000))
    sensor = load_profile(profile) if profile is not None else None
    typer.echo(threads_line)
    evaluate_kwargs = dict(
        settings=pairs,
        limit=limit,
        profile=profile,
        sweep=SweepOptions(sweep_poses, sweep_points, pairs[0][0], pairs[0][1]),
    )
    if report_only:  # the runs' saved evaluations, gathered again (nothing trained or evaluated)
        results = saved_results(cands, seed_list, out)
    else:
        results = run_compare(
            cands,
            seed_list,
            base,
            train_fields,
            data,
            out,
            evaluate_kwargs=evaluate_kwargs,
            profile=sensor,
            log=typer.echo,
        )
    context = {
        "split": data.resolve().name,
        "training": f"{base.image_size} px, widths {list(base.block_out_channels)}, "
        + ", ".join(
            f"{k} {','.join(map(str, step_list)) if k == 'steps' and len(step_list) > 1 else v}"
            for k, v in train_fields.items()
            if k in ("steps", "batch_size", "lr")
        )
        + "; the seed sets the initial weights, the data order and the noise",
        "evaluation": f"{', '.join(f'{s}:{n}' for s, n in pairs)}, noise seed 0, "
        + (f"at most {limit} frames per part" if limit else "every frame of each part")
        + f"; force sweep at up to {sweep_poses} poses (firm contact, see each report), {sweep_points} values",
        "machine": f"{describe()}; load average at the end {os.getloadavg()[0]:.1f}",
        "runs": "each in CANDIDATE/seed-S/ with its report (report/report.md)",
    }
    path = write_compare_report(
        summary(results),
        out,
        title=f"{len(cands)} settings × {len(seed_list)} seeds on {data.resolve().name}",
        context=context,
    )
    typer.echo(f"comparison: {path}")


def _step_counts(text: str | None) -> list[int]:
    """compare --steps: one or more whole numbers >= 1, comma-separated ([] when not given)."""
    if text is None:
        return []
    try:
        counts = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        counts = []
    if not counts or min(counts) < 1 or len(set(counts)) != len(counts):
        raise typer.BadParameter(f"--steps: expected different whole numbers >= 1, comma-separated, got {text!r}")
    return counts


def main() -> None:
    app()


def generate_main() -> None:
    generate_app()


def evaluate_main() -> None:
    evaluate_app()


def compare_main() -> None:
    compare_app()


if __name__ == "__main__":  # `accelerate launch -m cli.model_app ...`
    main()
