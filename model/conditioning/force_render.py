"""Physics conditioning where the force decides the depth: the render at the depth the measured Fz implies.

With ``physics_depth = "force"`` (model/denoiser/config.py) a frame's physics channels are the simulator's
render of its object at the frame's x, y, θ and at the depth where the simulator's contact (through
the run's sensor profile) presses with the frame's measured Fz — not at the pose's z. The network
then sees the wrench as a contact of the size it implies, the same way in training (this module's
cache), in a force sweep and in ``generate`` (model/generation/inference.py, ``force_pose``): a model trained
so cannot be told one contact size in training and another in a sweep. A force the simulator cannot
reach (past 1.5 gel thicknesses) is rendered at that deepest depth and said; Fz ≤ 0 is the object
touching without load.

On a real sensor without a force gauge the frames' Fz was derived (from the contact radius by Hertz,
for the GelSight presses): the render then turns that Fz back into a contact through the
simulator's own gel, which is monotone in Fz whatever the derivation.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader
from dataset.split import load_split
from model.conditioning import cache
from model.conditioning.physics_condition import PhysicsSpec, resize, split_spec

DEEPEST = 1.5  # gel thicknesses: how deep the simulator's depth search goes (sensor_sim/load_match.py)


def force_pose(renderer, pose, fz: float) -> tuple[np.ndarray, str]:
    """(x, y, z, θ) for the render of ``pose``'s x, y, θ at the depth where ``renderer``'s contact gives
    ``fz`` N, and a note: "" or why the depth is not Fz's (no load; beyond what the gel reaches)."""
    x, y, _, theta = (float(v) for v in pose)
    if not np.isfinite(fz) or fz <= 0:
        return np.array([x, y, 0.0, theta]), "no load: the object touching"
    try:
        return np.asarray(renderer.pose_at_force(x, y, theta, float(fz)), dtype=float), ""
    except ValueError as exc:  # past what the gel can give: the deepest the search goes
        deepest = DEEPEST * float(renderer.contact.solver.gel.thickness_mm)
        return np.array([x, y, -deepest, theta]), f"{exc}; rendered at {deepest:g} mm"


def render_at_force(renderer, pose, wrench: np.ndarray, fz: float, size: int, notes: set[str]) -> np.ndarray:
    """The render at ``pose``'s x, y, θ and the depth ``fz`` implies, under ``wrench`` with its Fz set to
    ``fz`` (its own dtype kept), resized to ``size``; a force past what the gel reaches is added to ``notes``."""
    moved = np.array(wrench, copy=True)
    moved[2] = fz
    at, note = force_pose(renderer, pose, fz)
    if note and "beyond" in note:
        notes.add(note)
    return resize(renderer.render(at, moved), size)


def force_physics_cache(
    split_dir: str | Path,
    part: str,
    size: int,
    spec: PhysicsSpec | None = None,
    *,
    log: Callable[[str], None] = lambda line: None,
) -> Path:
    """The part's physics renders at the depth each frame's Fz implies, at ``size`` px: a .npy of
    (frames, size, size, 3) BGR uint8 in the split's row order beside a .json of its key (the pose
    cache's key and ``"depth": "force"``), rebuilt when the key differs; what TactileDataset(physics=...)
    serves. Returns the .npy's path."""
    path = cache.force_renders(split_dir, part, size)
    key = cache.key(split_dir, part, size, (spec or split_spec(split_dir)).to_meta(), depth="force")
    if cache.fresh(path, key, log):
        return path
    manifest, parts = load_split(split_dir)
    rows = parts[part]
    spec = PhysicsSpec(**key["spec"])
    images = np.zeros((len(rows), size, size, 3), np.uint8)
    renderers: dict = {}
    recorded: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    notes: set[str] = set()
    step = max(1, len(rows) // 10)
    log(
        f"physics channels of {len(rows)} {part} frames: rendered at the depth each one's Fz implies, {size} px"
        " (cached)"
    )
    for k, (run, frame) in enumerate(rows):
        run, frame = int(run), int(frame)
        if run not in renderers:
            run_path = manifest["runs"][run]["path"]
            with RunReader.open(run_path) as f:
                recorded[run] = (f.rows[S.POSE_MEASURED], f.rows[S.WRENCH])
                renderers[run] = spec.renderer(f.text(S.ATTR_OBJECT), where=run_path)
        pose, wrench = recorded[run][0][frame], recorded[run][1][frame]
        images[k] = render_at_force(renderers[run], pose, wrench, float(wrench[2]), size, notes)
        if (k + 1) % step == 0 or k + 1 == len(rows):
            log(f"  physics channels: {k + 1}/{len(rows)} frames")
    for note in sorted(notes):
        log(f"  physics channels: {note}")
    cache.write(path, images, key)  # replaced whole, images first
    return path
