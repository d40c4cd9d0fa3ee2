"""What the force sweep compares the model with at each swept value: a real frame, or the physics render.

At a pose frame and a swept component, each value's reference is, in order:

1. **a real frame** of the same run at the pose's x, y (within 0.25 mm) and θ (within 1°), whose
   other swept components lie within half a training standard deviation of the pose frame's and
   whose swept component is nearest the value, within half a sweep step (``match_real_frames``);
2. else **the physics render**: for Fz at the depth the run's own Fz↔z relation gives
   (``depth_for_force``: binned medians of its frames in contact, made monotone), for Fx, Fy and
   Mz at the pose with the gel carrying the swept load (sensor_sim/load_match.py; it moves a
   marker sensor's markers and leaves a sensor without markers unchanged);
3. else none.

Each reference keeps its kind (``REAL`` or ``RENDER``): the two are never pooled, since a render
and a real frame of one contact can differ in area by several times on a real sensor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader

REAL = "real frame"
RENDER = "physics render"

# (run, pose x, y, z, θ, wrench N and N·mm) → BGR frame at the evaluated size, None: none
Physics = Callable[[int, np.ndarray, np.ndarray], "np.ndarray | None"]


@dataclass
class Reference:
    image: np.ndarray | None
    kind: str  # REAL, RENDER or "" (none)
    source: str  # in words: "real frame 41", "physics render at z -1.20 mm", ""


NONE = Reference(None, "", "")


def match_real_frames(
    wrench: np.ndarray,
    pose: np.ndarray,
    at: int,
    component: int,
    values: np.ndarray,
    std: np.ndarray,
    swept: tuple[int, ...] = (2, 0, 1, 5),
    *,
    xy_mm: float = 0.25,
    theta_deg: float = 1.0,
    others_std: float = 0.5,
) -> list[int | None]:
    """For each value of ``component``, the frame of the run (``wrench`` (n, 6), ``pose`` (n, 4)) at
    pose frame ``at``'s x, y (within ``xy_mm``) and θ (within ``theta_deg``) whose other ``swept``
    components lie within ``others_std`` training standard deviations of frame ``at``'s and whose
    ``component`` is nearest the value, within half a sweep step; None where there is none."""
    step = float(np.min(np.diff(values))) if len(values) > 1 else float("inf")
    near = (np.abs(pose[:, 0] - pose[at, 0]) <= xy_mm) & (np.abs(pose[:, 1] - pose[at, 1]) <= xy_mm)
    near &= np.abs(pose[:, 3] - pose[at, 3]) <= theta_deg
    for k in swept:
        if k != component:
            near &= np.abs(wrench[:, k] - wrench[at, k]) <= others_std * std[k]
    candidates = np.nonzero(near)[0]
    out: list[int | None] = []
    for v in values:
        if not len(candidates):
            out.append(None)
            continue
        gap = np.abs(wrench[candidates, component] - v)
        best = int(np.argmin(gap))
        out.append(int(candidates[best]) if gap[best] <= step / 2 else None)
    return out


def depth_for_force(fz: np.ndarray, z: np.ndarray, force: float, *, bins: int = 20) -> float | None:
    """The pose z (mm, negative into the gel) at which the run's frames show normal force ``force``:
    the median z of quantile bins of the frames in contact, made monotone (deeper for more force)
    and interpolated; None outside the run's range of force."""
    touching = np.isfinite(fz) & np.isfinite(z) & (fz > 0.02 * max(1e-9, float(np.nanmax(fz, initial=0.0))))
    f, d = fz[touching], z[touching]
    if len(f) < 3 or not (float(f.min()) <= force <= float(f.max())):
        return None
    edges = np.unique(np.quantile(f, np.linspace(0, 1, min(bins, len(f) // 2) + 1)))
    centres, depths = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        inside = (f >= lo) & (f <= hi)
        if inside.any():
            centres.append(float(np.median(f[inside])))
            depths.append(float(np.median(d[inside])))
    depths = list(np.minimum.accumulate(depths))  # more force never shallower
    return float(np.interp(force, centres, depths))


@dataclass
class RunData:
    """What the sweep reads of one run file, at the evaluated size. The file is opened (and verified,
    every frame: acquisition/run_reader.py) once, by ``load``, and kept open for ``frame``: each frame read
    is still checked by HDF5 as it is read. Opening it again for each frame cost 0.3–0.6 s a frame (the
    verification), most of `evaluate`'s time (docs/benchmarks.md, "The main job"). ``close`` closes it."""

    path: str
    wrench: np.ndarray  # (n, 6) N, N·mm
    pose: np.ndarray  # (n, 4) x, y, z mm, θ deg
    no_contact: np.ndarray  # the run's reference frame, resized
    mm_per_px: float  # at the evaluated size
    size: int
    reader: RunReader | None = field(default=None, repr=False, compare=False)  # open for ``frame``; None: not yet

    @classmethod
    def load(cls, path: str, size: int) -> "RunData":
        f = RunReader.open(path)
        try:
            wrench, pose = f.rows[S.WRENCH], f.rows[S.POSE_MEASURED]
            ref = f.image(S.REFERENCE_FRAME)
            mm_per_px = f.number(S.ATTR_MM_PER_PX)
            if not (math.isfinite(mm_per_px) and mm_per_px > 0):
                raise ValueError(f"{path}: mm_per_px {mm_per_px} is not a finite number > 0: no contact area in mm²")
        except BaseException:
            f.close()
            raise
        frame_px = ref.shape[1]
        return cls(path, wrench, pose, resize(ref, size), mm_per_px * frame_px / size, size, f)

    @property
    def name(self) -> str:
        return self.path.rsplit("/", 1)[-1]

    def frame(self, i: int) -> np.ndarray:
        if self.reader is None:
            self.reader = RunReader.open(self.path)
        return resize(self.reader.frame(i), self.size)

    def close(self) -> None:
        if self.reader is not None:
            self.reader.close()
            self.reader = None


def resize(img: np.ndarray, size: int) -> np.ndarray:
    return img if img.shape[:2] == (size, size) else cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)


def references_at(
    run: RunData,
    run_index: int,
    frame: int,
    component: int,
    name: str,
    values: np.ndarray,
    std: np.ndarray,
    swept: tuple[int, ...],
    physics: Physics | None,
) -> list[Reference]:
    """Each value's reference at pose frame ``frame`` of ``run`` (the module docstring's order)."""
    x, y, z, theta = (float(v) for v in run.pose[frame])
    w = run.wrench[frame]
    matches = match_real_frames(run.wrench, run.pose, frame, component, values, std, swept)
    out: list[Reference] = []
    for v, m in zip(values, matches):
        if m is not None:
            out.append(Reference(run.frame(m), REAL, f"{REAL} {m}"))
            continue
        load = w.copy()
        load[component] = v
        if name == "Fz":
            depth = depth_for_force(run.wrench[:, 2], run.pose[:, 2], float(v))
            if depth is None or physics is None:
                out.append(NONE)
                continue
            image = physics(run_index, np.array([x, y, depth, theta]), load)
            source = f"{RENDER} at z {depth:+.2f} mm"
        else:
            image = physics(run_index, np.array([x, y, z, theta]), load) if physics else None
            source = f"{RENDER} at {name} {v:+.2f}"
        out.append(Reference(image, RENDER, source) if image is not None else NONE)
    return out
