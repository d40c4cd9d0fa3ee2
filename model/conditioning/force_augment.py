"""Force augmentation: each training frame shown again at other loads, its contact grown or shrunk as
the simulator's contact grows or shrinks.

On a real sensor the frames' Fz and their place in the field go together (the GelSight presses:
Spearman ρ +0.79 between the derived Fz and the distance from the centre, docs/results/real-gelsight/
force-exponent.md), so a network that sees each press once learns the place's light, not the load:
its contact barely grows when Fz alone is swept at one place. ``ModelConfig.force_augment = s`` adds,
for every training frame, four items at Fz' = Fz × (1 − s, 1 − s/2, 1 + s/2, 1 + s):

- the physics channels: the render at the depth Fz' implies (model/conditioning/force_render.py's ``force_pose``);
- the wrench: Fz' in place of Fz;
- the frame: the run's no-contact frame plus the frame's change from it, scaled about the rendered
  contact's centre by √(A(Fz') / A(Fz)), A being the rendered contact's area (its change from the
  no-load render above a third of its peak). The real contact — its shading, rim and halo — grows as
  the simulator's contact grows, wherever it lies in the field.

That is an assumption, said where it is used: the contact keeps its look and changes size by the
simulator's gel (calibrated to the sensor) — for a sphere, Hertz's a ∝ Fz^⅓; a flat punch's area
does not grow and its frame is not scaled. The real frames cannot test it without a force gauge and
several loads per place. A frame without load (Fz ≤ 0) or without a rendered contact is shown
unchanged at every level. The renders and moved frames are made once per split part, size and s, at
the model's size, and kept next to the split like the other physics renders (``levels_cache``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import cv2
import numpy as np
import torch

from acquisition import schema as S
from acquisition.run_reader import RunReader
from dataset.split import load_split
from dataset.torch_dataset import image_to_tensor
from model.conditioning import cache
from model.conditioning.force_render import force_physics_cache, render_at_force
from model.conditioning.physics_condition import PhysicsSpec, resize, split_spec


def factors(span: float) -> tuple[float, ...]:
    """The Fz multipliers of the extra items for ``force_augment = span``."""
    return (1 - span, 1 - span / 2, 1 + span / 2, 1 + span)


def levels_cache(
    split_dir: str | Path,
    part: str,
    size: int,
    span: float,
    spec: PhysicsSpec | None = None,
    *,
    log: Callable[[str], None] = lambda line: None,
) -> Path:
    """The part's frames at Fz × ``factors(span)``: a .npy of (frames, levels, 2, size, size, 3) BGR uint8 in
    the split's row order — per level the render, then the frame moved to that load — beside a .json of its
    key, rebuilt when the key differs (the key names the runs' contents: new frames, new cache). Returns
    the .npy's path."""
    path = cache.force_levels(split_dir, part, size, span)
    key = cache.key(
        split_dir,
        part,
        size,
        (spec or split_spec(split_dir)).to_meta(),
        depth="force",
        force_factors=list(factors(span)),
        moved="scaled about the rendered contact by sqrt of its area ratio",
    )
    if cache.fresh(path, key, log):
        return path
    manifest, parts = load_split(split_dir)
    rows = parts[part]
    spec = PhysicsSpec(**key["spec"])
    own_renders = np.load(force_physics_cache(split_dir, part, size, spec, log=log))  # at each frame's own Fz
    scale = key["force_factors"]
    images = np.zeros((len(rows), len(scale), 2, size, size, 3), np.uint8)
    runs: dict = {}
    readers: dict[int, RunReader] = {}
    notes: set[str] = set()
    step = max(1, len(rows) // 10)
    log(f"force augmentation: {len(rows)} {part} frames at Fz × {', '.join(f'{f:g}' for f in scale)} (cached)")
    try:
        for k, (run, frame) in enumerate(rows):
            run, frame = int(run), int(frame)
            if run not in runs:
                run_path = manifest["runs"][run]["path"]
                f = readers[run] = RunReader.open(run_path)
                renderer = spec.renderer(f.text(S.ATTR_OBJECT), where=run_path)
                runs[run] = (
                    f.rows[S.POSE_MEASURED],
                    f.rows[S.WRENCH],
                    resize(f.image(S.REFERENCE_FRAME), size),
                    renderer,
                )
            poses, wrenches, reference, renderer = runs[run]
            tactile = resize(readers[run].frame(frame), size)
            pose, wrench = poses[frame], np.asarray(wrenches[frame], dtype=float)
            fz, own = float(wrench[2]), own_renders[k]
            bare = render_at_force(renderer, pose, wrench, 0.0, size, notes)
            for j, factor in enumerate(scale):
                images[k, j, 0] = render_at_force(renderer, pose, wrench, fz * factor, size, notes)
                images[k, j, 1] = grown(tactile, reference, own, images[k, j, 0], bare)
            if (k + 1) % step == 0 or k + 1 == len(rows):
                log(f"  force augmentation: {k + 1}/{len(rows)} frames")
    finally:
        for f in readers.values():
            f.close()
    for note in sorted(notes):
        log(f"  force augmentation: {note}")
    cache.write(path, images, key)
    return path


def contact(render: np.ndarray, bare: np.ndarray, peak: float) -> tuple[float, float, float]:
    """(area px, centre x, centre y) of a render's contact: its change from the no-load render ``bare``
    above a third of ``peak`` (the frame's own render's largest change)."""
    change = np.abs(render.astype(np.float32) - bare.astype(np.float32)).sum(axis=2)
    inside = change > peak / 3
    if not inside.any():
        return 0.0, 0.0, 0.0
    ys, xs = np.nonzero(inside)
    return float(inside.sum()), float(xs.mean()), float(ys.mean())


def grown(tactile, reference, own, render, bare) -> np.ndarray:
    """``tactile`` (BGR uint8) with its change from ``reference`` scaled about the rendered contact's centre
    by √(A(render) / A(own)); unchanged when the frame's own render shows no contact."""
    peak = float(np.abs(own.astype(np.float32) - bare.astype(np.float32)).sum(axis=2).max())
    area_own, cx, cy = contact(own, bare, peak)
    area = contact(render, bare, peak)[0]
    if peak <= 0 or area_own <= 0 or area <= 0 or area == area_own:
        return tactile.copy()
    ratio = float(np.sqrt(area / area_own))
    warp = np.array([[ratio, 0.0, (1 - ratio) * cx], [0.0, ratio, (1 - ratio) * cy]], dtype=np.float64)
    change = tactile.astype(np.float32) - reference.astype(np.float32)
    h, w = change.shape[:2]
    moved = cv2.warpAffine(change, warp, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    return np.clip(np.rint(reference.astype(np.float32) + moved), 0, 255).astype(np.uint8)


class ForceAugmented(torch.utils.data.Dataset):
    """``base`` (a TactileDataset serving ``physics`` at each frame's own Fz) followed by each of its frames
    at every level of ``levels`` (``levels_cache``'s array): item ``i`` < len(base) is base's, item
    ``(1 + j)·len(base) + i`` is frame i at level j. A function of the index alone, as the trainer needs."""

    def __init__(self, base, levels: np.ndarray, span: float):
        expected = (len(base), len(factors(span)), 2)
        if levels.shape[:3] != expected or levels.dtype != np.uint8:
            raise ValueError(
                f"force augmentation images {levels.shape} {levels.dtype}: expected {expected} frames × levels × "
                "(render, frame) uint8 (a stale cache); rebuild it with `train`"
            )
        self.base, self.levels, self.factors = base, levels, factors(span)
        self.manifest = base.manifest
        self.mm_per_px = base.mm_per_px

    def __len__(self) -> int:
        return len(self.base) * (1 + len(self.factors))

    def __getitem__(self, index: int) -> dict:
        level, i = divmod(int(index), len(self.base))
        item = self.base[i]
        if level == 0:
            return item
        render, moved = (image_to_tensor(np.asarray(a)) for a in self.levels[i, level - 1])
        wrench = item["wrench"].clone()
        mean, std = float(self.base.mean[2]), float(self.base.std[2])
        fz = float(wrench[2]) * std + mean
        wrench[2] = (fz * self.factors[level - 1] - mean) / std
        return item | {"tactile": moved, "physics": render, "wrench": wrench}
