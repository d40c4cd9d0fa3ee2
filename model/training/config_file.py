"""``train --config model.toml``: a preset, then [model] and [train] tables over it.

    preset = "tiny"            # optional: the starting point (tiny | paper)
    [model]                    # any ModelConfig field (model/denoiser/config.py)
    image_size = 64
    conditioning = "plane"
    [train]                    # any TrainConfig field (model/training/trainer.py)
    steps = 4000

Every key is checked against the dataclass it sets; errors name the file and the key.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from common.errors import ConfigError
from common.table import Table, toml_table


def _fields(table: Table, defaults) -> dict:
    """The table's keys typed by the dataclass defaults they replace."""
    out = {}
    for f in dataclasses.fields(defaults):
        if f.name not in table.data:
            continue
        default = getattr(defaults, f.name)
        if isinstance(default, tuple):
            value = table.data[f.name]
            table.used.add(f.name)
            if (
                not isinstance(value, list)
                or not value
                or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)
            ):
                raise table.error(f.name, f"must be a list of whole numbers, got {value!r}")
            out[f.name] = tuple(value)
        else:
            out[f.name] = table.get(f.name, type(default))
    table.done()
    return out


def load_model_file(path: str | Path, preset_name: str | None = None):
    """(ModelConfig, dict of TrainConfig fields: the preset's, then the file's) from a model
    TOML; ``preset_name`` (the command line's) wins over the file's ``preset``."""
    from model.denoiser.config import PRESET_TRAINING, PRESETS, ModelConfig
    from model.training.trainer import TrainConfig

    path = str(path)
    try:
        text = Path(path).read_text()
    except FileNotFoundError:
        raise ConfigError(path, "-", "file not found") from None
    top, _ = toml_table(text, path)
    name = preset_name or top.get("preset", str, "tiny", choices=tuple(PRESETS))
    model_fields = _fields(Table(path, "model", top.get("model", dict, {})), PRESETS[name])
    train_fields = _fields(Table(path, "train", top.get("train", dict, {})), TrainConfig())
    top.done()
    try:
        model_cfg = ModelConfig(**{**dataclasses.asdict(PRESETS[name]), **model_fields})
    except ValueError as exc:
        raise ConfigError(path, "model", str(exc)) from None
    return model_cfg, {**PRESET_TRAINING[name], **train_fields}
