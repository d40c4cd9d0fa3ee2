"""torchvision.transforms.v2: Transform is a base class the reader subclasses at import (RandomSubsetApply,
SharpnessJitter); every transform (ColorJitter, RandomAffine, ...) raises when built, Identity excepted."""

from __future__ import annotations

from typing import Any

import torch

from .._missing import missing
from . import functional

__all__ = ["Transform", "Identity", "functional"]


class Transform(torch.nn.Module):
    def forward(self, *inputs: Any) -> Any:
        raise NotImplementedError(
            f"torchvision stub (tests/lerobot_reader): transforms.v2.Transform ({type(self).__name__}) cannot run"
        )

    def _call_kernel(self, *args: Any, **kwargs: Any) -> Any:
        raise NotImplementedError("torchvision stub (tests/lerobot_reader): transforms.v2 kernels are not implemented")


class Identity(Transform):
    def forward(self, *inputs: Any) -> Any:
        return inputs[0] if len(inputs) == 1 else inputs


def __getattr__(name: str) -> Any:
    if name.startswith("__"):
        raise AttributeError(name)
    return missing(f"transforms.v2.{name}")
