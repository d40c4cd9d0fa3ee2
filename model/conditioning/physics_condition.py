"""Physics conditioning: the simulator's render of each frame at its measured pose, as condition channels.

A ``physics`` model (``ModelConfig.uses_physics``) sees, beside the object image, the physics
render of the frame (model/conditioning/baseline.py's ``ObjectRender``: the split's object at the measured
pose x, y, z, θ through the run's sensor profile, over the simulator's own background, no
noise; for marker sensors the gel's tangential state is the one that carries the measured
Fx, Fy and Mz, so the markers move as the load says), resized to the model's size like the frames. Rendering takes tens
of milliseconds a frame, so a split part's renders are made once per size and kept next to the
split (``physics_cache``); ``TactileDataset(physics=...)`` serves them as the ``physics`` item
field. Inference renders the same image from what the checkpoint records (``PhysicsSpec``).

Every run of the split must show a library object (the simulator knows its shape) and share one
sensor kind and one sensor profile, which each run records (``train --profile FILE`` gives one for
runs that record none: a real sensor's, an import without ``--profile``; it is never guessed);
otherwise ``PhysicsUnavailable`` says which run and why. ``--profile`` never silently replaces the
profile a run records: another profile than the run's is ``ProfileMismatch``, naming both, unless
``train --override-profile`` says so; which profile renders each run is said (``split_spec``'s ``log``).
The split's values (object, sensor, scale, profile) are read back from the run files
(dataset/split_manifest.py's ``check_unchanged``): an edited ``split.json`` is refused, never used.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader
from common.errors import ToolError
from dataset.split import check_unchanged, load_split
from model.conditioning import cache
from model.conditioning.baseline import BaselineUnavailable, NoProfile, ObjectRender, no_profile


class PhysicsUnavailable(BaselineUnavailable):
    """Physics conditioning asked for where the simulator cannot render the frames (one line)."""


class PhysicsNoProfile(PhysicsUnavailable, NoProfile):
    """Physics conditioning of a run that records no sensor profile, with no ``--profile`` given."""


class ProfileMismatch(ToolError):
    """``--profile`` gives another profile than a run records, without ``--override-profile``: an error,
    not a reason to fall back to other conditioning."""


@dataclass(frozen=True)
class PhysicsSpec:
    """What renders a split's physics channels; recorded in a physics model's checkpoint."""

    sensor_kind: str
    profile_record: str  # the profile's record: the runs' sensor_profile attribute, or train --profile's
    mm_per_px: float  # the frames' scale...
    frame_px: int  # ...at this many pixels across (the render's size before resizing)
    frame_height_px: int | None = None  # ...and down; None: frame_px (square, as every spec before it)

    def profile(self, where: str = "checkpoint"):
        from sensor_sim.profile import ProfileError, profile_from_record

        if not self.profile_record.strip():
            raise PhysicsNoProfile(
                f"{where}: [physics] profile_record is empty: this model was trained before a run said which "
                "sensor profile it has, so its physics channels' profile is unknown; retrain it (train --profile FILE "
                "for runs without one)"
            )
        try:
            return profile_from_record(self.profile_record, where=where)
        except ProfileError as exc:
            raise PhysicsUnavailable(str(exc)) from None

    def renderer(self, obj: str, where: str = "") -> ObjectRender:
        return ObjectRender(
            obj,
            self.sensor_kind,
            self.profile(where or "checkpoint"),
            (self.frame_px, self.frame_height_px or self.frame_px),
            self.mm_per_px,
            where=where,
        )

    @classmethod
    def from_meta(cls, raw, where: str) -> "PhysicsSpec":
        """From a checkpoint's ``physics`` entry, checked (PhysicsUnavailable naming ``where``)."""
        if not isinstance(raw, dict):
            raise PhysicsUnavailable(f"{where}: [physics] expected the physics render's record, got {raw!r}")
        kind, record, mm, px = (raw.get(k) for k in ("sensor_kind", "profile_record", "mm_per_px", "frame_px"))
        if not isinstance(kind, str) or not isinstance(record, str):
            raise PhysicsUnavailable(f"{where}: [physics] sensor_kind and profile_record must be text")
        if not (isinstance(mm, (int, float)) and not isinstance(mm, bool) and np.isfinite(mm) and mm > 0):
            raise PhysicsUnavailable(f"{where}: [physics] mm_per_px expected a positive number, got {mm!r}")
        if not (isinstance(px, int) and not isinstance(px, bool) and 8 <= px <= 8192):
            raise PhysicsUnavailable(f"{where}: [physics] frame_px expected a whole number in [8, 8192], got {px!r}")
        tall = raw.get("frame_height_px")  # absent or None: a square frame (checkpoints before non-square ones)
        if tall is not None and not (isinstance(tall, int) and not isinstance(tall, bool) and 8 <= tall <= 8192):
            raise PhysicsUnavailable(
                f"{where}: [physics] frame_height_px expected a whole number in [8, 8192], got {tall!r}"
            )
        return cls(kind, record, float(mm), px, tall)

    def to_meta(self) -> dict:
        return asdict(self)


def split_spec(
    split_dir: str | Path, profile=None, *, override: bool = False, log: Callable[[str], None] = lambda line: None
) -> PhysicsSpec:
    """The split's PhysicsSpec, or PhysicsUnavailable naming the run the simulator cannot render.
    ``profile``: a SensorProfile for every run (``train --profile``); default: each run's recorded
    one, which must be the same for all (a run that records none: PhysicsNoProfile). A run that
    records another profile than ``profile``: ProfileMismatch unless ``override``. ``log`` hears
    which profile renders each run."""
    from objects.indenters import INDENTERS

    manifest, _ = load_split(split_dir)
    check_unchanged(manifest, split_dir)  # the runs' values read back from the files, not split.json's word
    specs = set()
    for run in manifest["runs"]:
        path = run["path"]
        obj = run["object"]
        h, w = run["frame_shape"][:2]
        if obj not in INDENTERS:
            raise PhysicsUnavailable(
                f"{path}: object {obj!r} is not one the simulator knows ({', '.join(INDENTERS)}): no physics "
                "render, so no physics conditioning; train with --conditioning plane+embedding"
            )
        recorded = run["sensor_profile"]
        log(f"{path}: physics conditioning through sensor profile {_source(path, recorded, profile, override)}")
        record = profile.record() if profile is not None else recorded
        if not record.strip():
            raise PhysicsNoProfile(str(no_profile(path, "physics conditioning", "train --profile FILE")))
        mm = float(run["mm_per_px"])
        specs.add(PhysicsSpec(run["sensor"], record, mm, int(w), int(h)))
    if len(specs) != 1:
        detail = "; ".join(f"{s.sensor_kind}, {s.mm_per_px:g} mm/px, {s.frame_px} px" for s in specs)
        raise PhysicsUnavailable(
            f"{split_dir}: physics conditioning needs one sensor kind, profile and scale across the runs; "
            f"they differ ({detail})"
        )
    spec = specs.pop()
    spec.profile(str(split_dir))  # a recorded profile that cannot be found again: one line now
    return spec


def _source(path: str, recorded: str, profile, override: bool) -> str:
    """Which profile renders a run, in words; ProfileMismatch for ``profile`` over another recorded one
    unless ``override``."""
    from sensor_sim.profile import ProfileError, parse_record

    if not recorded.strip():
        if profile is None:
            return "none (the run records none)"
        return f"{_named(profile)} (given by --profile; the run records none)"
    try:
        rec = parse_record(recorded, where=path)
    except ProfileError as exc:
        raise PhysicsUnavailable(str(exc)) from None
    mine = f"{rec['name']} (sha256 {rec['sha256'][:12]}…, file {rec['file'] or '?'})"
    if profile is None:
        return f"{mine} (recorded in the run)"
    if profile.content_hash() == rec["sha256"]:
        return f"{mine} (recorded in the run; --profile gives the same)"
    if not override:
        raise ProfileMismatch(
            f"{path}: records sensor profile {mine}, but --profile gives {_named(profile)}; leave --profile out to "
            "use the run's, or pass --override-profile to render this run through the given one"
        )
    return f"{_named(profile)} (given by --profile over the run's recorded {mine}: --override-profile)"


def _named(profile) -> str:
    return f"{profile.name} (sha256 {profile.content_hash()[:12]}…, file {profile.path})"


def physics_cache(
    split_dir: str | Path,
    part: str,
    size: int,
    spec: PhysicsSpec | None = None,
    *,
    log: Callable[[str], None] = lambda line: None,
) -> Path:
    """The part's physics renders at ``size`` px through ``spec`` (default: ``split_spec``'s), (frames, size,
    size, 3) BGR uint8 in the split's row order, as a .npy beside a .json of its key; rebuilt when
    the key differs (other runs, rows, size, profile or render version). Returns the .npy's path."""
    path = cache.pose_renders(split_dir, part, size)
    key = cache.key(split_dir, part, size, (spec or split_spec(split_dir)).to_meta())
    if cache.fresh(path, key, log):
        return path
    manifest, parts = load_split(split_dir)
    rows = parts[part]
    spec = PhysicsSpec(**key["spec"])
    images = np.zeros((len(rows), size, size, 3), np.uint8)
    renderers: dict[int, ObjectRender] = {}
    poses: dict[int, np.ndarray] = {}
    wrenches: dict[int, np.ndarray] = {}
    step = max(1, len(rows) // 10)
    log(f"physics channels of {len(rows)} {part} frames: rendered at {size} px (once; cached in {path.parent})")
    for k, (run, frame) in enumerate(rows):
        run = int(run)
        if run not in renderers:
            run_path = manifest["runs"][run]["path"]
            with RunReader.open(run_path) as f:
                obj = f.text(S.ATTR_OBJECT)
                poses[run] = f.rows[S.POSE_MEASURED]
                wrenches[run] = f.rows[S.WRENCH]
            renderers[run] = spec.renderer(obj, where=run_path)
        images[k] = resize(renderers[run].render(poses[run][int(frame)], wrenches[run][int(frame)]), size)
        if (k + 1) % step == 0 or k + 1 == len(rows):
            log(f"  physics render: {k + 1}/{len(rows)} frames")
    cache.write(path, images, key)
    return path


def resize(bgr: np.ndarray, size: int) -> np.ndarray:
    """As the dataset resizes a frame to the model's size."""
    return bgr if bgr.shape[:2] == (size, size) else cv2.resize(bgr, (size, size), interpolation=cv2.INTER_AREA)
