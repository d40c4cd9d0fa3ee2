"""A split's derived caches: the one place that knows where each lives, what it is keyed on, whether it is
still fresh, and how it is written.

Every cache of the physics channels is a .npy beside a .json of its key, in ``SPLIT/physics/`` (``folder``):

- ``pose_renders``: ``PART-SIZEpx.npy``, the render at each frame's pose (physics_condition.py);
- ``force_renders``: ``PART-SIZEpx-fz.npy``, the render at the depth each frame's Fz implies (force_render.py);
- ``force_levels``: ``PART-SIZEpx-fz-augment-S.npy``, each frame at other loads (force_augment.py).

A cache's key (``key``) names the runs' identities, the part's rows, the size and what renders them, so
a cache of another split, size or profile is stale (``fresh``) and is rebuilt; ``write`` replaces the
images and then the key, each file whole.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Callable

import numpy as np

from dataset.split import load_split

CACHE_DIR = "physics"  # inside the split directory
CACHE_VERSION = 3  # bump when the render or the cache layout changes: every cache is rebuilt (3: issue 26 optics)


def folder(split_dir: str | Path) -> Path:
    """Where a split's derived caches live."""
    return Path(split_dir) / CACHE_DIR


def pose_renders(split_dir: str | Path, part: str, size: int) -> Path:
    """The part's physics renders at each frame's measured pose, at ``size`` px."""
    return folder(split_dir) / f"{part}-{size}px.npy"


def force_renders(split_dir: str | Path, part: str, size: int) -> Path:
    """The part's physics renders at the depth each frame's Fz implies, at ``size`` px."""
    return folder(split_dir) / f"{part}-{size}px-fz.npy"


def force_levels(split_dir: str | Path, part: str, size: int, span: float) -> Path:
    """The part's frames and renders at Fz × force augmentation's factors for ``span``, at ``size`` px."""
    return folder(split_dir) / f"{part}-{size}px-fz-augment-{span:g}.npy"


def key(split_dir: str | Path, part: str, size: int, spec: dict, **more) -> dict:
    """What a cache depends on: the runs' identities, the part's rows, the size, the render's inputs
    (``spec``: a PhysicsSpec's ``to_meta()``), then ``more`` (what sets this cache apart)."""
    manifest, parts = load_split(split_dir)
    return {
        "version": CACHE_VERSION,
        "part": part,
        "size": int(size),
        "rows_sha1": hashlib.sha1(np.ascontiguousarray(parts[part]).tobytes()).hexdigest(),
        "runs": [[r["path"], r["identity"]["sha256"]] for r in manifest["runs"]],
        "spec": spec,
        **more,
    }


def fresh(path: Path, key: dict, log: Callable[[str], None]) -> bool:
    """Whether the render cache ``path`` exists with the .json key ``key`` beside it; a stale
    one (another split, size or profile) is said in ``log`` and is to be rebuilt."""
    meta = path.with_suffix(".json")
    if not (path.is_file() and meta.is_file()):
        return False
    try:
        if json.loads(meta.read_text()) == key:
            return True
    except (OSError, json.JSONDecodeError):
        pass
    log(f"physics channels cache {path}: stale (the split, size or profile changed); rebuilding")
    return False


def write(path: Path, images: np.ndarray, key: dict) -> None:
    """The render cache and its key beside it. Each file replaced whole, images first: a reader
    (another process of a multi-GPU run, which renders the same images) never sees half a file,
    and a crash before the key leaves the old key, which no longer matches: the next run rebuilds."""
    meta = path.with_suffix(".json")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npy")
    np.save(tmp, images)
    os.replace(tmp, path)
    tmp_meta = meta.with_name(f"{meta.stem}.{os.getpid()}.tmp.json")
    tmp_meta.write_text(json.dumps(key, indent=1) + "\n")
    os.replace(tmp_meta, meta)
