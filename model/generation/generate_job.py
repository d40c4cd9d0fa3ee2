"""The ``generate`` command's work: a trained model loaded, one frame made and written, or a split's part.

``generate(options, log)`` loads the checkpoint on the device asked for (``device``), then either
generates every frame of a split's part (``TrainedModel.generate_split``) or one frame for an
object (``object_image``: a picture, a library object or a run file), a wrench and a pose, resized
if asked and written as an image. What it did comes back as data (``Generated``) for the command
to word.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable


@dataclass(frozen=True)
class GenerateOptions:
    """``generate``'s options as parsed; ``wrench`` and ``pose`` already checked (None with ``split``)."""

    checkpoint: Path
    out: Path
    object_source: str | None = None
    wrench: tuple[float, ...] | None = None
    pose: tuple[float, ...] | None = None
    split: Path | None = None
    part: str = "test"
    limit: int | None = None
    steps: int = 50
    sampler: str = "ddim"
    guidance: float = 1.0
    seed: int = 0
    size: int | None = None
    device: str | None = None
    precision: str = "auto"  # the network's arithmetic (model/denoiser/precision.py)


@dataclass(frozen=True)
class Generated:
    """What ``generate`` wrote. With a split: ``frames`` written to the folder. Otherwise one image of
    ``width`` x ``height`` from a model whose own size is ``native``; ``physics_z``: the depth the
    physics condition was rendered at where the model chose it from the wrench's Fz (else None)."""

    out: Path
    frames: int | None = None
    width: int = 0
    height: int = 0
    native: int = 0
    physics_z: float | None = None


def generate(opts: GenerateOptions, log: Callable[[str], None]) -> Generated:
    """Load the model and generate what the options ask for (see the module's docstring)."""
    import cv2
    import numpy as np

    from model.generation.inference import TrainedModel

    model = TrainedModel.load(opts.checkpoint, device_for(opts.device), opts.precision)
    if opts.split is not None:
        written = model.generate_split(
            opts.split,
            opts.part,
            opts.out,
            limit=opts.limit,
            steps=opts.steps,
            sampler=opts.sampler,
            seed=opts.seed,
            guidance=opts.guidance,
            log=log,
        )
        return Generated(opts.out, frames=written)
    assert opts.object_source is not None and opts.wrench is not None and opts.pose is not None  # the command checks
    w, p = np.asarray(opts.wrench), list(opts.pose)
    img = object_image(opts.object_source, model.frame_px, model.mm_per_px)
    frame = model.generate(
        img,
        w,
        p,
        steps=opts.steps,
        sampler=opts.sampler,
        seed=opts.seed,
        guidance=opts.guidance,
        object_name=object_name(opts.object_source) if model.cfg.uses_physics else None,
    )
    native, size = frame.shape[0], opts.size
    if size is not None and size != native:
        frame = cv2.resize(frame, (size, size), interpolation=cv2.INTER_CUBIC if size > native else cv2.INTER_AREA)
    z = None
    if model.cfg.uses_physics and (len(p) == 3 or model.cfg.force_depth):
        z = model.physics_pose(object_name(opts.object_source), p, w)[2]
    write_image(opts.out, frame)
    return Generated(opts.out, width=frame.shape[1], height=frame.shape[0], native=native, physics_z=z)


def device_for(device: str | None) -> str:
    """--device checked against this machine; None: cuda when available, else cpu."""
    import torch

    if device is None:
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device.split(":")[0] not in ("cpu", "cuda"):
        raise ValueError(f"--device: expected cpu or cuda, got {device!r}")
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise ValueError("--device cuda: no CUDA device is available here")
    return device


def object_image(source: str, frame_px: int, mm_per_px: float):
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


def object_name(source: str) -> str:
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


def write_image(path: Path, image) -> None:
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
