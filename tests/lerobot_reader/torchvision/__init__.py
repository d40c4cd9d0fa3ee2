"""A stub of torchvision, just enough for LeRobot's dataset reader (ledataset) to import and read.

PyPI's torchvision wheels are built against one torch each and do not import against the project's torch;
the reader needs from it only `transforms.ToTensor` (image features), `transforms.v2` names at import time
(training augmentations, never used here), `set_video_backend` and `io.VideoReader` (the "pyav" video
backend). What can work here works (ToTensor, and VideoReader through PyAV); the rest raises
NotImplementedError naming this stub the moment it is used. tests/lerobot_support.py puts this folder
first on PYTHONPATH of the reader's process only; the project itself never imports torchvision.
"""

from __future__ import annotations

from . import io, transforms

__version__ = "0.0.0+tactile-rig-stub"
__all__ = ["io", "transforms", "set_video_backend", "get_video_backend"]

_BACKENDS = ("pyav",)
_backend = "pyav"


def set_video_backend(backend: str) -> None:
    """Only "pyav" (io.VideoReader here decodes with PyAV); "video_reader" and "cuda" need the real build."""
    global _backend
    if backend not in _BACKENDS:
        raise NotImplementedError(
            f"torchvision stub (tests/lerobot_reader): video backend {backend!r} is not available, only 'pyav'"
        )
    _backend = backend


def get_video_backend() -> str:
    return _backend
