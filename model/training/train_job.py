"""The ``train`` command's work: the configs settled from the options, the trainer built and run.

``train(options, log)`` reads the model TOML or the preset, fills what the options leave open
(the measured best conditioning and target for the split's sensor kind, model/denoiser/config.py), sets
torch's threads, builds the trainer (model/training/build.py), trains and saves. ``log`` gets every line
the run says while it runs, in order (on the main process only, except those each process says
of itself); the checkpoint folder comes back for the command to print.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable


@dataclass(frozen=True)
class TrainOptions:
    """``train``'s options as parsed; None: not given (the config's, else the preset's)."""

    data: Path
    out: Path
    config: Path | None = None
    preset: str | None = None
    image_size: int | None = None
    conditioning: str | None = None
    prediction: str | None = None
    target: str | None = None
    physics_depth: str | None = None
    residual_gain: float | None = None
    force_augment: float | None = None
    steps: int | None = None
    batch_size: int | None = None
    lr: float | None = None
    checkpoint_every: int | None = None
    sample_every: int | None = None
    seed: int | None = None
    mixed_precision: str | None = None
    resume: bool = False
    device: str | None = None
    profile: Path | None = None
    override_profile: bool = False
    threads: int | None = None


@dataclass(frozen=True)
class Trained:
    """A finished run: where its checkpoint is, and whether this process is the one that says so."""

    checkpoint: Path | None
    is_main: bool
    processes: int = 1
    kept: object = field(default=None, repr=False, compare=False)  # several processes: the trainer, never freed


def train(opts: TrainOptions, log: Callable[[str], None]) -> Trained:
    """Settle the configs, build the trainer, train and save; ``log`` says each step as it comes."""
    import dataclasses

    from model.denoiser.config import PRESET_TRAINING
    from model.denoiser.config import preset as make_preset
    from model.denoiser.threads import set_threads
    from model.training.build import build
    from model.training.config_file import load_model_file
    from model.training.trainer import TrainConfig
    from sensor_sim.profile import load_profile

    sensor = load_profile(opts.profile) if opts.profile is not None else None  # a bad file: ProfileError, one line
    if opts.config is not None:
        model_cfg, train_fields = load_model_file(opts.config, opts.preset)
    else:
        preset = opts.preset or "tiny"
        model_cfg, train_fields = make_preset(preset), dict(PRESET_TRAINING.get(preset, {}))
    model_over = {
        k: getattr(opts, k)
        for k in (
            "image_size",
            "conditioning",
            "prediction",
            "target",
            "physics_depth",
            "residual_gain",
            "force_augment",
        )
        if getattr(opts, k) is not None
    }
    if opts.conditioning is None and not names_key(opts.config, "conditioning"):
        model_over["conditioning"], best_target = default_for_split(opts.data, sensor, opts.override_profile, log=log)
        if opts.target is None and not names_key(opts.config, "target"):
            model_over["target"] = best_target
    if model_over:
        model_cfg = dataclasses.replace(model_cfg, **model_over)
    given = {
        k: getattr(opts, k)
        for k in ("steps", "batch_size", "lr", "checkpoint_every", "sample_every", "seed", "mixed_precision")
    }
    cfg = TrainConfig(**{**train_fields, **{k: v for k, v in given.items() if v is not None}})
    threads_line = set_threads(opts.threads)  # before anything runs; said once the run is set up (one-line errors)
    trainer = build(
        model_cfg,
        cfg,
        opts.data,
        opts.out,
        device=opts.device,
        log=log,
        profile=sensor,
        override_profile=opts.override_profile,
    )
    say = log if trainer.is_main else (lambda line: None)
    say(threads_line)
    if opts.resume:
        trainer.resume()
        say(f"resumed at step {trainer.step}")
    say(describe(model_cfg, trainer))
    trainer.train()
    if trainer.acc.num_processes > 1:  # every process says what it read: its own shard of each epoch
        log(
            f"process {trainer.acc.process_index} of {trainer.acc.num_processes}: read {len(trainer.read)} of "
            f"{len(trainer.data)} training items (its share of each step's batch)"
        )
    saved = trainer.save()
    if trainer.acc.num_processes == 1:
        return Trained(saved, trainer.is_main)
    trainer.acc.wait_for_everyone()  # every process here: the checkpoint is written
    return Trained(saved, trainer.is_main, trainer.acc.num_processes, kept=trainer)


def end_process(trained: Trained) -> None:
    """A run on several processes ends its process here, once what it says is said: ``os._exit(0)``
    with nothing torn down (hence ``Trained.kept``). Freeing the DDP model frees gloo's process group,
    whose destructor joins gloo's worker threads while holding the GIL; a worker still freeing the last
    barrier's work (which holds the step's reduced loss, a Python tensor) waits for the GIL: a deadlock,
    seen in CI and in 1 of ~20 launches under load. Left to the interpreter's exit instead, gloo's threads
    were destroyed while joinable (SIGABRT, "terminate called without an active exception"). One process:
    returns."""
    if trained.processes > 1:
        _exit_now(0)


def end_failed_process(code: int, say: str | None = None) -> None:
    """A process of a run on several processes that failed (an error said, Ctrl-C) ends here the same way,
    ``os._exit(code)``: left to the interpreter, the model and the process group it holds would be freed
    as above, ``say`` first (a line to stderr). Returns when no process group is up (one process: the usual
    way out)."""
    import sys

    dist = sys.modules.get("torch.distributed")  # never imports torch: a group is up only if it was imported
    if dist is not None and dist.is_available() and dist.is_initialized():
        if say:
            sys.stderr.write(say + "\n")
        _exit_now(code)


def _exit_now(code: int) -> None:
    import os
    import sys

    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def describe(model_cfg, trainer) -> str:
    """The line a run starts with: the network, its conditioning and target, the data and the devices."""
    from model.conditioning.force_augment import factors

    return (
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
        + (f", {trainer.acc.mixed_precision} arithmetic" if trainer.acc.mixed_precision != "no" else "")
        + (f" x {trainer.acc.num_processes} processes" if trainer.acc.num_processes > 1 else "")
    )


def names_key(config: Path | None, key: str) -> bool:
    """Whether a model TOML sets [model] ``key`` (then it wins over the per-sensor default)."""
    import tomllib

    if config is None:
        return False
    try:
        return key in tomllib.loads(config.read_text()).get("model", {})
    except (OSError, tomllib.TOMLDecodeError, AttributeError):
        return False  # load_model_file reports the bad file in one line


def default_for_split(
    split: Path, profile=None, override_profile: bool = False, *, log: Callable[[str], None]
) -> tuple[str, str]:
    """The measured best conditioning and target for the split's sensor kind (model/denoiser/config.py);
    plane+embedding and the frame, said in a line, where the best is physics and the simulator
    cannot render the split's runs (an object it does not know, a run without a sensor profile
    and no --profile)."""
    from dataset.split import check_unchanged, load_split
    from model.conditioning.physics_condition import PhysicsUnavailable, split_spec
    from model.denoiser.config import ModelConfig, default_conditioning, default_target

    manifest, _ = load_split(split)
    check_unchanged(manifest, split)  # the sensor kind read back from the run files, never split.json's word alone
    kinds = {str(r.get("sensor", "")) for r in manifest["runs"]}
    kind = kinds.pop() if len(kinds) == 1 else ""
    best = default_conditioning(kind)
    if ModelConfig(conditioning=best).uses_physics:
        try:
            split_spec(split, profile, override=override_profile)
        except PhysicsUnavailable as exc:
            log(f"conditioning plane+embedding, not the default {best}: {exc}")
            return "plane+embedding", "frame"
    return best, default_target(kind, best)
