"""Checkpoint files: reading and writing in one place.

A checkpoint is a folder ``RUN/checkpoint/`` of safetensors files (tensors only, no
pickle, so loading one runs no code) and ``state.json`` (the step, the configs and
the conditioning statistics). Everything read from it is checked before use: a
damaged, foreign or truncated file is a ``CheckpointError`` naming the file.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path
from typing import Any

import torch
from safetensors import SafetensorError
from safetensors.torch import load_file, save_file

from common.errors import ToolError
from model.denoiser.config import ModelConfig

STATE = "state.json"
MODEL = "model.safetensors"
EMA = "ema.safetensors"
OPTIMIZER = "optimizer.safetensors"
CONDITIONING_KEYS = ("wrench_mean", "wrench_std", "mm_per_px", "frame_px")


class CheckpointError(ToolError, ValueError):
    """A checkpoint is missing, damaged or does not fit; the message names the file."""


def folder(run_dir: str | Path) -> Path:
    return Path(run_dir) / "checkpoint"


def run_folder(path: str | Path) -> Path:
    """The training folder (``train --out DIR``) that ``path`` names: DIR itself, DIR/checkpoint, or a file
    in it (DIR/checkpoint/state.json), so that `--checkpoint` takes whichever a user copies."""
    p = Path(path)
    if p.is_file() and p.parent.name == "checkpoint":
        return p.parent.parent
    if p.name == "checkpoint" and (p / STATE).is_file() and not (folder(p) / STATE).is_file():
        return p.parent
    return p


def write_tensors(ck: Path, name: str, tensors: dict[str, torch.Tensor]) -> None:
    """Write atomically: a crash mid-write leaves the previous file, never half a file."""
    tmp = ck / (name + ".tmp")
    save_file({k: v.contiguous() for k, v in tensors.items()}, str(tmp))
    os.replace(tmp, ck / name)


def write_state(ck: Path, meta: dict) -> None:
    tmp = ck / (STATE + ".tmp")
    tmp.write_text(json.dumps(meta))
    os.replace(tmp, ck / STATE)


def read_tensors(ck: Path, name: str, device: str | torch.device = "cpu") -> dict[str, torch.Tensor]:
    path = ck / name
    if not path.is_file():
        raise CheckpointError(f"{path}: missing (an incomplete checkpoint)")
    try:
        return load_file(str(path), device=str(device))
    except (SafetensorError, OSError, ValueError, RuntimeError) as exc:
        raise CheckpointError(f"{path}: not a safetensors file ({_first_line(exc)})") from None


def read_state(ck: Path, *, hint: str = "") -> dict:
    """state.json, checked: a JSON object with a step and a model config this code knows."""
    path = ck / STATE
    if not path.is_file():
        raise CheckpointError(f"{ck}: no checkpoint{hint}")
    try:
        meta = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CheckpointError(f"{path}: not readable JSON ({_first_line(exc)})") from None
    if not isinstance(meta, dict):
        raise CheckpointError(f"{path}: expected a JSON object, got {type(meta).__name__}")
    step = meta.get("step")
    if not isinstance(step, int) or isinstance(step, bool) or step < 0:
        raise CheckpointError(f"{path}: [step] expected a whole number >= 0, got {step!r}")
    model_config(meta, path)  # raises on unknown or malformed keys
    return meta


def model_config(meta: dict, path: Path) -> ModelConfig:
    raw = meta.get("model")
    if not isinstance(raw, dict):
        raise CheckpointError(f"{path}: [model] expected a table of the model config, got {type(raw).__name__}")
    known = {f.name for f in dataclasses.fields(ModelConfig)}
    unknown = sorted(set(raw) - known)
    if unknown:
        raise CheckpointError(
            f"{path}: [model] unknown key(s) {', '.join(map(repr, unknown))}: written by another "
            f"version of this software? (known: {', '.join(sorted(known))})"
        )
    try:
        fields: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in raw.items()}
        return ModelConfig(**fields)
    except (TypeError, ValueError) as exc:
        raise CheckpointError(f"{path}: [model] {_first_line(exc)}") from None


def conditioning(meta: dict, path: Path) -> tuple[list[float], list[float], float, int]:
    """(wrench mean, wrench std, mm per px, frame px) that inference conditions with, checked."""
    missing = [k for k in CONDITIONING_KEYS if k not in meta]
    if missing:
        raise CheckpointError(
            f"{path}: has no conditioning statistics ({', '.join(missing)}): it predates them; "
            "train on (with --resume) to write a complete checkpoint"
        )
    mean, std, mm_per_px, frame_px = meta["wrench_mean"], meta["wrench_std"], meta["mm_per_px"], meta["frame_px"]
    for key, vec in (("wrench_mean", mean), ("wrench_std", std)):
        if not (isinstance(vec, list) and len(vec) == 6 and all(_finite(v) for v in vec)):
            raise CheckpointError(f"{path}: [{key}] expected six finite numbers, got {vec!r}")
    if not all(v > 0 for v in std):
        raise CheckpointError(f"{path}: [wrench_std] expected positive numbers, got {std!r}")
    if not (_finite(mm_per_px) and mm_per_px > 0):
        raise CheckpointError(f"{path}: [mm_per_px] expected a positive number, got {mm_per_px!r}")
    if not (isinstance(frame_px, int) and not isinstance(frame_px, bool) and 8 <= frame_px <= 8192):
        raise CheckpointError(f"{path}: [frame_px] expected a whole number of pixels in [8, 8192], got {frame_px!r}")
    return mean, std, float(mm_per_px), frame_px


def physics_record(meta: dict, path: Path) -> dict | None:
    """A physics-conditioned model's render record (model/conditioning/physics_condition.py's PhysicsSpec
    fields), None for the other conditionings; a physics model without one is an error."""
    cfg = model_config(meta, path)
    if not cfg.uses_physics:
        return None
    raw = meta.get("physics")
    if not isinstance(raw, dict):
        raise CheckpointError(
            f"{path}: [physics] missing: a {cfg.conditioning!r} model needs the record of its physics render "
            "(sensor kind, profile, scale); retrain it"
        )
    return raw


def write_training_state(ck: Path, state: dict, meta: dict) -> None:
    """A trainer's ``state()`` (weights, EMA, optimizer, noise generator, step, losses) and ``meta``
    (configs, conditioning statistics) as the files above; state.json last, so a folder with one
    is a complete checkpoint."""
    ck.mkdir(parents=True, exist_ok=True)
    write_tensors(ck, MODEL, state["model"])
    write_tensors(ck, EMA, state["ema"])
    opt = state["optimizer"]
    tensors = {
        f"{pid}.{key}": v for pid, st in opt["state"].items() for key, v in st.items() if isinstance(v, torch.Tensor)
    }
    tensors["noise_generator_state"] = state["noise"]
    write_tensors(ck, OPTIMIZER, tensors)
    write_state(ck, {**meta, "step": state["step"], "param_groups": opt["param_groups"], "losses": state["losses"]})


def read_training_state(ck: Path, meta: dict) -> dict:
    """What ``write_training_state`` wrote, in the trainer's ``state()`` form, on the CPU (the
    trainer's load puts each tensor where its parameter is). ``meta``: ``read_state(ck)``."""
    tensors = read_tensors(ck, OPTIMIZER)
    noise = tensors.pop("noise_generator_state", None)
    if noise is None:
        raise CheckpointError(f"{ck / OPTIMIZER}: no noise_generator_state (an incomplete checkpoint)")
    state: dict = {}
    for name, v in tensors.items():
        pid, _, key = name.partition(".")
        if not pid.isdigit() or not key:
            raise CheckpointError(f"{ck / OPTIMIZER}: unexpected tensor {name!r}")
        state.setdefault(int(pid), {})[key] = v
    if not isinstance(meta.get("losses"), list) or not isinstance(meta.get("param_groups"), list):
        raise CheckpointError(f"{ck / STATE}: [losses] and [param_groups] expected lists: no training state to resume")
    return {
        "step": meta["step"],
        "losses": meta["losses"],
        "model": read_tensors(ck, MODEL),
        "ema": read_tensors(ck, EMA),
        "optimizer": {"state": state, "param_groups": meta["param_groups"]},
        "noise": noise,
    }


def load_weights(module: torch.nn.Module, ck: Path, name: str, device: str | torch.device = "cpu") -> None:
    try:
        module.load_state_dict(read_tensors(ck, name, device))
    except RuntimeError as exc:
        raise CheckpointError(f"{ck / name}: weights do not fit this model: {_first_line(exc)}") from None


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
