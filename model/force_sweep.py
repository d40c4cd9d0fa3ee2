"""The force-response check: does the generated contact respond to the wrench as the real one does?

At a few test poses, one wrench component at a time (Fz, Fx, Fy, Mz) is swept over its
training range (the split's 2nd to 98th percentile) with the condition image and the
other components held at the pose frame's own values. Each generated frame is measured
against the run's no-contact frame (``measure_contact``): the contact's area (pixels
differing beyond a threshold), its centroid and its shading (the mean intensity change
inside it). The same measures are taken on a reference at each force: the real frame of
the same run nearest in that component at the same x, y, θ with the other components
close (``match_real_frames``), else the physics render: for Fz at the depth the run's own
Fz↔z relation gives (``depth_for_force``), for Fx, Fy and Mz at the pose with the gel's
tangential state carrying the swept load (sensor_sim/load_match.py; it moves a marker
sensor's markers and leaves a sensor without markers unchanged, as the simulator does).
``summarise`` gives Spearman's ρ of each measure against the force, its least-squares
slope, the sign consistency of successive steps, and the error against the reference.

numpy, OpenCV and the verified run-file reader only: the generator is a callable, so every measure here is
tested on synthetic frames without a network.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import cv2
import numpy as np
from numpy.typing import ArrayLike

from acquisition import schema as S
from acquisition.run_reader import RunReader
from common.eta import Eta

COMPONENTS = {"Fz": 2, "Fx": 0, "Fy": 1, "Mz": 5}  # the swept components, index into the six-axis wrench
UNITS = {"Fz": "N", "Fx": "N", "Fy": "N", "Mz": "N·mm"}
MEASURES = ("area_mm2", "centroid_x_mm", "centroid_y_mm", "shading")
ALONG = {"Fx": "centroid_x_mm", "Fy": "centroid_y_mm"}  # the centroid coordinate a shear force moves
MONOTONIC_RHO = 0.8  # |Spearman ρ| at least this: the measure follows the force monotonically
THRESHOLD = 8.0  # 0–255: a pixel is in contact when its blurred change from the no-contact frame exceeds this


@dataclass
class ContactMeasure:
    area_px: int
    area_mm2: float
    centroid_x_mm: float  # from the image centre, +x to the right (columns)
    centroid_y_mm: float  # from the image centre, +y down (rows)
    shading: float  # mean |change| (0–255, all channels) inside the contact; 0 without contact


def measure_contact(
    image: np.ndarray,
    reference: np.ndarray,
    *,
    mm_per_px: float,
    threshold: float = THRESHOLD,
    blur_px: float = 1.0,
) -> ContactMeasure:
    """The contact in ``image`` as its change from the no-contact ``reference`` (both (H, W, 3) uint8,
    same size): both blurred with a Gaussian of σ ``blur_px`` (sensor noise and, for marker sensors,
    the markers' own motion stay below the threshold), the per-pixel change the largest over channels."""
    if image.shape != reference.shape:
        raise ValueError(f"image {image.shape} and no-contact reference {reference.shape} differ in shape")
    if not (math.isfinite(mm_per_px) and mm_per_px > 0):
        raise ValueError(f"mm_per_px must be a finite number > 0, got {mm_per_px}")
    a: np.ndarray = image.astype(np.float32)
    b: np.ndarray = reference.astype(np.float32)
    if blur_px > 0:
        a = cv2.GaussianBlur(a, (0, 0), blur_px)
        b = cv2.GaussianBlur(b, (0, 0), blur_px)
    change = np.abs(a - b)
    strength = change.max(axis=2)
    mask = strength > threshold
    n = int(mask.sum())
    if n == 0:
        return ContactMeasure(0, 0.0, float("nan"), float("nan"), 0.0)
    rows, cols = np.nonzero(mask)
    weight = strength[mask]
    h, w = strength.shape
    cx = (float(np.average(cols, weights=weight)) - (w - 1) / 2) * mm_per_px
    cy = (float(np.average(rows, weights=weight)) - (h - 1) / 2) * mm_per_px
    return ContactMeasure(n, n * mm_per_px**2, cx, cy, float(change[mask].mean()))


def spearman(x: ArrayLike, y: ArrayLike) -> float:
    """Spearman's rank correlation (ties share their mean rank); nan when either side is constant
    or fewer than three finite pairs remain."""
    a, b = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    keep = np.isfinite(a) & np.isfinite(b)
    a, b = a[keep], b[keep]
    if len(a) < 3:
        return float("nan")
    ra, rb = _ranks(a), _ranks(b)
    if np.ptp(ra) == 0 or np.ptp(rb) == 0:
        return float("nan")
    return float(np.corrcoef(ra, rb)[0, 1])


def _ranks(v: np.ndarray) -> np.ndarray:
    order = np.argsort(v, kind="mergesort")
    ranks = np.empty(len(v))
    ranks[order] = np.arange(len(v), dtype=np.float64)
    for value in np.unique(v):  # ties: the mean of their ranks
        same = v == value
        if same.sum() > 1:
            ranks[same] = ranks[same].mean()
    return ranks


def slope(x: ArrayLike, y: ArrayLike) -> float:
    """Least-squares slope of y on x over the finite pairs (nan with fewer than two)."""
    a, b = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    keep = np.isfinite(a) & np.isfinite(b)
    if keep.sum() < 2 or np.ptp(a[keep]) == 0:
        return float("nan")
    return float(np.polyfit(a[keep], b[keep], 1)[0])


def sign_consistency(y: ArrayLike, expected_sign: float, tolerance: float = 0.0) -> float:
    """The fraction of successive steps of ``y`` that move with ``expected_sign`` (+1 or −1); steps
    smaller than ``tolerance`` count as not moving (so a flat response scores 0, not 1)."""
    d = np.diff(np.asarray(y, dtype=np.float64))
    d = d[np.isfinite(d)]
    if not len(d) or expected_sign == 0 or not math.isfinite(expected_sign):
        return float("nan")
    return float(np.mean(np.sign(expected_sign) * d > tolerance))


def power_exponent(force: ArrayLike, area: ArrayLike) -> float:
    """The exponent k of area ∝ force^k by least squares in log–log over positive pairs (Hertz: a
    sphere's contact radius grows as F^(1/3), its area as F^(2/3))."""
    f, a = np.asarray(force, dtype=np.float64), np.asarray(area, dtype=np.float64)
    keep = np.isfinite(f) & np.isfinite(a) & (f > 0) & (a > 0)
    return slope(np.log(f[keep]), np.log(a[keep])) if keep.sum() >= 2 else float("nan")


def sweep_values(low: float, high: float, points: int) -> np.ndarray:
    """``points`` evenly spaced values from ``low`` to ``high`` (the component's training range)."""
    if not (math.isfinite(low) and math.isfinite(high)) or points < 2:
        raise ValueError(f"a sweep needs a finite range and at least 2 points, got [{low}, {high}] × {points}")
    return np.linspace(low, high, points)


def match_real_frames(
    wrench: np.ndarray,
    pose: np.ndarray,
    at: int,
    component: int,
    values: np.ndarray,
    std: np.ndarray,
    *,
    xy_mm: float = 0.25,
    theta_deg: float = 1.0,
    others_std: float = 0.5,
) -> list[int | None]:
    """For each value of ``component``, the frame of the run (``wrench`` (n, 6), ``pose`` (n, 4)) at
    pose frame ``at``'s x, y (within ``xy_mm``) and θ (within ``theta_deg``) whose other swept components
    lie within ``others_std`` training standard deviations of frame ``at``'s and whose ``component`` is
    nearest the value, within half a sweep step; None where there is none."""
    step = float(np.min(np.diff(values))) if len(values) > 1 else float("inf")
    near = (np.abs(pose[:, 0] - pose[at, 0]) <= xy_mm) & (np.abs(pose[:, 1] - pose[at, 1]) <= xy_mm)
    near &= np.abs(pose[:, 3] - pose[at, 3]) <= theta_deg
    for k in COMPONENTS.values():
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
class PoseSweep:
    """One component swept at one pose: the generated frames, the references and their measures."""

    component: str
    label: str  # the pose frame: run, frame, pose and wrench, in words
    values: list[float]
    model: list[ContactMeasure]
    reference: list[ContactMeasure | None]
    sources: list[str]  # where each reference came from: "real frame N", "physics render at z ...", ""
    images: list[np.ndarray] = field(default_factory=list)
    reference_images: list[np.ndarray | None] = field(default_factory=list)
    reference_mse: list[float | None] = field(default_factory=list)  # generated against reference, 0–255²


def _series(measures: Sequence[ContactMeasure | None], key: str) -> np.ndarray:
    return np.array([getattr(m, key) if m is not None else float("nan") for m in measures], dtype=np.float64)


def summarise(sweep: PoseSweep, area_tolerance_mm2: float = 0.0) -> dict:
    """Per measure: ρ and slope of the model and of the reference against the swept value, the mean
    absolute error where a reference exists; for the area the sign consistency of successive steps
    against the reference's direction (Fz without a reference: growing) and whether it is monotonic
    (|ρ| ≥ MONOTONIC_RHO, in that direction where there is one); for Fz the power-law exponent."""
    x = np.asarray(sweep.values, dtype=np.float64)
    out: dict = {
        "component": sweep.component,
        "pose": sweep.label,
        "values": list(sweep.values),
        "sources": list(sweep.sources),
        "references": int(sum(r is not None for r in sweep.reference)),
        "model_area_mm2": _series(sweep.model, "area_mm2").tolist(),
        "reference_area_mm2": _series(sweep.reference, "area_mm2").tolist(),
    }
    for key in MEASURES:
        m, r = _series(sweep.model, key), _series(sweep.reference, key)
        both = np.isfinite(m) & np.isfinite(r)
        out[key] = {
            "rho": spearman(x, m),
            "slope": slope(x, m),
            "reference_rho": spearman(x, r),
            "reference_slope": slope(x, r),
            "mae": float(np.mean(np.abs(m[both] - r[both]))) if both.any() else float("nan"),
        }
    area = out["area_mm2"]
    direction = area["reference_rho"] if math.isfinite(area["reference_rho"]) else float("nan")
    if sweep.component == "Fz" and not math.isfinite(direction):
        direction = 1.0  # pressing harder never shrinks the contact
    out["area_sign_consistency"] = sign_consistency(_series(sweep.model, "area_mm2"), direction, area_tolerance_mm2)
    # monotonic: |ρ| large, and in the reference's direction where there is one (Fz: growing)
    rho = area["rho"]
    out["monotonic"] = bool(
        math.isfinite(rho) and (rho * direction if math.isfinite(direction) else abs(rho)) >= MONOTONIC_RHO
    )
    if sweep.component == "Fz":  # k of area ∝ Fz^k: over every point, and over the points with a reference
        model_area, ref_area = _series(sweep.model, "area_mm2"), _series(sweep.reference, "area_mm2")
        matched = np.isfinite(ref_area)
        out["area_exponent"] = power_exponent(x, model_area)
        out["area_exponent_matched"] = power_exponent(x[matched], model_area[matched])
        out["reference_area_exponent"] = power_exponent(x[matched], ref_area[matched])
    mses = [v for v in sweep.reference_mse if v is not None]
    out["image_mse"] = float(np.mean(mses)) if mses else float("nan")
    return out


Generate = Callable[[int, np.ndarray], list[np.ndarray]]  # (pose index, raw wrenches (k, 6)) → k frames


def sweep_pose(
    generate: Generate,
    pose_index: int,
    component: str,
    values: np.ndarray,
    base_wrench: np.ndarray,
    *,
    no_contact: np.ndarray,
    mm_per_px: float,
    references: Sequence[tuple[np.ndarray | None, str]],
    label: str = "",
    threshold: float = THRESHOLD,
    blur_px: float = 1.0,
) -> PoseSweep:
    """Generate the sweep of ``component`` at one pose (the other components at ``base_wrench``),
    measure every frame and its reference (an image and its source, or None)."""
    k = COMPONENTS[component]
    wrenches = np.repeat(np.asarray(base_wrench, dtype=np.float64)[None], len(values), axis=0)
    wrenches[:, k] = values
    images = generate(pose_index, wrenches)
    if len(images) != len(values):
        raise ValueError(f"the generator returned {len(images)} frames for {len(values)} wrenches")

    def measure(img):
        return measure_contact(img, no_contact, mm_per_px=mm_per_px, threshold=threshold, blur_px=blur_px)

    ref_images = [img for img, _ in references]
    return PoseSweep(
        component,
        label,
        [float(v) for v in values],
        [measure(img) for img in images],
        [measure(img) if img is not None else None for img in ref_images],
        [src for _, src in references],
        list(images),
        ref_images,
        [
            float(np.mean((img.astype(np.float64) - ref.astype(np.float64)) ** 2)) if ref is not None else None
            for img, ref in zip(images, ref_images)
        ],
    )


def training_range(percentiles: dict, component: str) -> tuple[float, float]:
    """The sweep range of a component: the split's 2nd and 98th percentile of the training wrench."""
    k = COMPONENTS[component]
    low, high = float(percentiles["p2"][k]), float(percentiles["p98"][k])
    if not (math.isfinite(low) and math.isfinite(high)):
        raise ValueError(f"the split's {component} percentiles are not finite: {low}, {high}")
    return low, high


def choose_poses(
    rows: np.ndarray, wrench_of: Callable[[int], np.ndarray], pose_of: Callable[[int], np.ndarray], n: int, std
) -> list[tuple[int, int]]:
    """``n`` pose frames (run, frame) from a part's ``rows``: firm contact (Fz between the part's 40th
    and 90th percentile), least shear (|Fx|/σx + |Fy|/σy) first, taken from the runs in turn and at
    least 0.5 mm apart within a run, so the poses differ."""
    runs = sorted({int(r) for r in rows[:, 0]})
    per_run: dict[int, list[int]] = {}
    fz_all = np.concatenate([wrench_of(r)[rows[rows[:, 0] == r][:, 1], 2] for r in runs]) if runs else np.zeros(0)
    if not len(fz_all):
        return []
    lo, hi = np.percentile(fz_all, [40, 90])
    for r in runs:
        frames = rows[rows[:, 0] == r][:, 1]
        w = wrench_of(r)[frames]
        firm = (w[:, 2] >= lo) & (w[:, 2] <= hi)
        shear = np.abs(w[:, 0]) / std[0] + np.abs(w[:, 1]) / std[1]
        per_run[r] = [int(frames[i]) for i in np.nonzero(firm)[0][np.argsort(shear[firm], kind="stable")]]
    chosen: list[tuple[int, int]] = []
    while len(chosen) < n and any(per_run.values()):
        for r in runs:
            while per_run[r] and len(chosen) < n:
                f = per_run[r].pop(0)
                xy = pose_of(r)[f, :2]
                if all(rr != r or np.linalg.norm(pose_of(r)[ff, :2] - xy) >= 0.5 for rr, ff in chosen):
                    chosen.append((r, f))
                    break
    return chosen


def _mean_of(rows: list[dict], key: str, sub: str = "mae") -> float:
    v = np.array([s[key][sub] for s in rows], dtype=np.float64)
    return float(np.nanmean(v)) if np.isfinite(v).any() else float("nan")


def component_table(summaries: list[dict], ranges: dict[str, tuple[float, float]]) -> list[str]:
    """Markdown rows, one per swept component: the model's monotonicity and its error against the reference."""

    def f(v, fmt="{:.2f}"):
        return fmt.format(v) if isinstance(v, float) and math.isfinite(v) else "—"

    lines = [
        "| component | swept over | poses | area ρ, model (mean; min) | area ρ, reference | centroid ρ along it, "
        "model / reference | monotonic poses "
        "| area sign consistency | area error, mm² | centroid error, mm | shading error | area ∝ Fz^k where both, "
        "model / reference | references |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, (low, high) in ranges.items():
        rows = [s for s in summaries if s["component"] == name]
        if not rows:
            continue
        rho = np.array([s["area_mm2"]["rho"] for s in rows], dtype=np.float64)
        ref_rho = np.array([s["area_mm2"]["reference_rho"] for s in rows], dtype=np.float64)
        cons = np.array([s["area_sign_consistency"] for s in rows], dtype=np.float64)

        cx, cy = _mean_of(rows, "centroid_x_mm"), _mean_of(rows, "centroid_y_mm")
        centroid = math.hypot(cx, cy) if math.isfinite(cx) and math.isfinite(cy) else float("nan")
        rho_text = f"{np.nanmean(rho):+.2f}; {np.nanmin(rho):+.2f}" if np.isfinite(rho).any() else "— (no response)"
        ref_text = f"{np.nanmean(ref_rho):+.2f}" if np.isfinite(ref_rho).any() else "—"
        along = ALONG.get(name)
        centroid_rho = "—"
        if along:
            cm = np.array([s[along]["rho"] for s in rows], dtype=np.float64)
            cr = np.array([s[along]["reference_rho"] for s in rows], dtype=np.float64)
            centroid_rho = " / ".join(f"{np.nanmean(v):+.2f}" if np.isfinite(v).any() else "—" for v in (cm, cr))
        expo = "—"
        if name == "Fz":
            k = np.array([s["area_exponent_matched"] for s in rows], dtype=np.float64)
            kr = np.array([s["reference_area_exponent"] for s in rows], dtype=np.float64)
            expo = (
                f"{f(float(np.nanmean(k)) if np.isfinite(k).any() else float('nan'))} / "
                f"{f(float(np.nanmean(kr)) if np.isfinite(kr).any() else float('nan'))}"
            )
        refs = sum(s["references"] for s in rows)
        points = sum(len(s.get("values", [])) for s in rows) or "—"
        lines.append(
            f"| {name} | {low:+.2f} … {high:+.2f} {UNITS[name]} | {len(rows)} | {rho_text} | {ref_text} "
            f"| {centroid_rho} "
            f"| {sum(s['monotonic'] for s in rows)}/{len(rows)} "
            f"| {f(float(np.nanmean(cons)) if np.isfinite(cons).any() else float('nan'))} "
            f"| {f(_mean_of(rows, 'area_mm2'))} | {f(centroid)} | {f(_mean_of(rows, 'shading'), '{:.1f}')} "
            f"| {expo} | {refs}/{points} |"
        )
    return lines


@dataclass
class RunData:
    """What the sweep reads of one run file, at the evaluated size."""

    path: str
    wrench: np.ndarray  # (n, 6) N, N·mm
    pose: np.ndarray  # (n, 4) x, y, z mm, θ deg
    no_contact: np.ndarray  # the run's reference frame, resized
    mm_per_px: float  # at the evaluated size
    size: int

    @classmethod
    def load(cls, path: str, size: int) -> "RunData":
        with RunReader.open(path) as f:
            wrench, pose = f.rows[S.WRENCH], f.rows[S.POSE_MEASURED]
            ref = f.image(S.REFERENCE_FRAME)
            mm_per_px = f.number(S.ATTR_MM_PER_PX)
        if not (math.isfinite(mm_per_px) and mm_per_px > 0):
            raise ValueError(f"{path}: mm_per_px {mm_per_px} is not a finite number > 0: no contact area in mm²")
        frame_px = ref.shape[1]
        return cls(path, wrench, pose, _resize(ref, size), mm_per_px * frame_px / size, size)

    def frame(self, i: int) -> np.ndarray:
        with RunReader.open(self.path) as f:
            return _resize(f.frame(i), self.size)


def _resize(img: np.ndarray, size: int) -> np.ndarray:
    return img if img.shape[0] == size else cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)


# (run, pose x, y, z, θ, wrench N and N·mm) → BGR frame, None: none
Physics = Callable[[int, np.ndarray, np.ndarray], "np.ndarray | None"]


def run_force_sweep(
    generate: Generate,
    runs: dict[int, RunData],
    poses: list[tuple[int, int]],
    ranges: dict[str, tuple[float, float]],
    std: np.ndarray,
    *,
    points: int = 7,
    physics: Physics | None = None,
    blur_px: float = 1.0,
    threshold: float = THRESHOLD,
    log: Callable[[str], None] = lambda line: None,
    clock: Callable[[], float] = time.perf_counter,
) -> list[PoseSweep]:
    """Every component of ``ranges`` swept at every pose (``generate(pose index, raw wrenches)``),
    each point beside its reference: a matching real frame, else the ``physics`` render (for Fz at
    the depth the run's own Fz↔z relation gives), else none."""
    eta = Eta(len(poses) * len(ranges), clock)
    out: list[PoseSweep] = []
    for p, (r, f) in enumerate(poses):
        run = runs[r]
        x, y, z, theta = (float(v) for v in run.pose[f])
        w = run.wrench[f]
        label = (
            f"{run.path.rsplit('/', 1)[-1]} frame {f}: x {x:+.2f} y {y:+.2f} z {z:+.2f} mm theta {theta:+.1f} deg, "
            f"Fz {w[2]:.2f} N Fx {w[0]:+.2f} Fy {w[1]:+.2f} Mz {w[5]:+.1f} Nmm"
        )
        for name, (low, high) in ranges.items():
            values = sweep_values(low, high, points)
            matches = match_real_frames(run.wrench, run.pose, f, COMPONENTS[name], values, std)
            refs: list[tuple[np.ndarray | None, str]] = []
            for v, m in zip(values, matches):
                if m is not None:
                    refs.append((run.frame(m), f"real frame {m}"))
                    continue
                load = w.copy()
                load[COMPONENTS[name]] = v
                if name == "Fz":
                    depth = depth_for_force(run.wrench[:, 2], run.pose[:, 2], float(v))
                    rendered = (
                        physics(r, np.array([x, y, depth, theta]), load) if depth is not None and physics else None
                    )
                    source = f"physics render at z {depth:+.2f} mm" if depth is not None else ""
                else:
                    rendered = physics(r, np.array([x, y, z, theta]), load) if physics else None
                    source = f"physics render at {name} {v:+.2f}"
                refs.append((rendered, source) if rendered is not None else (None, ""))
            out.append(
                sweep_pose(
                    generate,
                    p,
                    name,
                    values,
                    w,
                    no_contact=run.no_contact,
                    mm_per_px=run.mm_per_px,
                    references=refs,
                    label=label,
                    threshold=threshold,
                    blur_px=blur_px,
                )
            )
            done = len(out)
            log(f"force sweep: {name} at pose {p + 1}/{len(poses)}: {done}/{eta.total} sweeps, {eta.line(done)}")
    return out
