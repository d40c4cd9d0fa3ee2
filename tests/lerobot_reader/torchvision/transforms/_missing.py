"""A placeholder for a torchvision name the reader imports but the harness never uses."""

from __future__ import annotations

from typing import Any


def missing(name: str) -> Any:
    def fail(*args: Any, **kwargs: Any) -> Any:
        raise NotImplementedError(
            f"torchvision stub (tests/lerobot_reader): torchvision.{name} is not implemented; the LeRobot "
            "harness reads datasets without image transforms (install a torchvision built for this torch to use it)"
        )

    fail.__name__ = name.rsplit(".", 1)[-1]
    fail.__qualname__ = fail.__name__
    return fail
