"""torchvision.transforms.v2.functional: nothing implemented; any kernel raises when called."""

from __future__ import annotations

from typing import Any

from .._missing import missing


def __getattr__(name: str) -> Any:
    if name.startswith("__"):
        raise AttributeError(name)
    return missing(f"transforms.v2.functional.{name}")
