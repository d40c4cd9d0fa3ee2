"""torchvision.transforms: ToTensor works (the reader turns image features into tensors with it); other
names exist for import's sake and raise when used."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from . import v2
from ._missing import missing

__all__ = ["ToTensor", "v2"]


class ToTensor:
    """PIL image or HWC uint8 array -> float32 tensor (C, H, W) in [0, 1], as torchvision's ToTensor."""

    def __call__(self, pic: Any) -> torch.Tensor:
        if isinstance(pic, torch.Tensor):
            raise TypeError("torchvision stub ToTensor: expects a PIL image or a numpy array, got a tensor")
        if hasattr(pic, "mode") and pic.mode not in ("RGB", "L", "I", "F", "I;16", "1", "RGBA", "CMYK", "YCbCr"):
            pic = pic.convert("RGB")
        arr = np.array(pic, copy=True)
        if arr.ndim == 2:
            arr = arr[:, :, None]
        out = torch.from_numpy(arr).permute(2, 0, 1).contiguous()
        if out.dtype == torch.uint8:
            return out.to(torch.float32).div(255)
        if out.dtype == torch.bool:
            return out.to(torch.float32)
        return out.to(torch.float32)

    def __repr__(self) -> str:
        return "ToTensor()"


def __getattr__(name: str) -> Any:
    if name.startswith("__"):
        raise AttributeError(name)
    return missing(f"transforms.{name}")
