"""The force-response check: does the generated contact respond to the wrench as the real one does?

At a few test poses, one wrench component at a time (Fz, Fx, Fy, Mz) is swept over its
training range (the split's 2nd to 98th percentile; a component whose range is zero — an
import without shear — is skipped and said so, ``swept_ranges``), with the condition image and the
other components held at the pose frame's own values; Fz also a little past the training
maximum (``beyond``), to see how the model degrades where it was never trained. Each generated
frame is measured against the run's no-contact frame (model/sweeps/sweep_measures.py), and so is each
point's reference, a real frame or the physics render (model/sweeps/sweep_references.py), kept apart
by kind. ``summarise`` gives per sweep Spearman's ρ of each measure against the force, its
slope, the error against each kind of reference, whether the area is monotonic in the
direction the references show, and for Fz the exponent k of area ∝ Fz^k within the training
range. The report is model/sweeps/sweep_report.py.

numpy, OpenCV and the verified run-file reader only: the generator is a callable, so every measure here is
tested on synthetic frames without a network.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from common.eta import Eta
from common.wording import signed
from model.sweeps.sweep_measures import (
    THRESHOLD,
    ContactMeasure,
    measure_contact,
    power_exponent,
    sign_consistency,
    slope,
    spearman,
)
from model.sweeps.sweep_poses import (  # noqa: F401 (choose_poses, pose_runs, swept_ranges, training_range: moved there)
    COMPONENTS,
    UNITS,
    choose_poses,
    pose_range,
    pose_runs,
    swept_ranges,
    training_range,
)
from model.sweeps.sweep_references import NONE, REAL, RENDER, Physics, Reference, RunData, references_at

MEASURES = ("area_mm2", "centroid_x_mm", "centroid_y_mm", "shading")
ALONG = {"Fx": "centroid_x_mm", "Fy": "centroid_y_mm"}  # the centroid coordinate a shear force moves
MONOTONIC_RHO = 0.8  # |Spearman ρ| at least this: the measure follows the force monotonically
KINDS = {REAL: "real", RENDER: "render"}  # reference kinds and their keys in a summary


@dataclass
class PoseSweep:
    """One component swept at one pose: the generated frames, the references and their measures."""

    component: str
    label: str  # the pose frame: run, frame, pose and wrench, in words
    values: list[float]
    model: list[ContactMeasure]
    reference: list[ContactMeasure | None]
    sources: list[str]  # where each reference came from: "real frame N", "physics render at z ...", ""
    kinds: list[str] = field(default_factory=list)  # REAL, RENDER or "" per point
    inside: list[bool] = field(default_factory=list)  # the value lies within the training range
    run: str = ""  # the pose frame's run file (name)
    images: list[np.ndarray] = field(default_factory=list)
    reference_images: list[np.ndarray | None] = field(default_factory=list)
    reference_mse: list[float | None] = field(default_factory=list)  # generated against reference, 0–255²
    outside_change: list[float] = field(default_factory=list)  # mean change away from the contact, 0–255
    notes: list[str] = field(default_factory=list)  # per point: why its physics channels are not at the value ("")
    range_note: str = ""  # how this pose's range differs from the split's training range, in words


def _series(measures: Sequence[ContactMeasure | None], key: str, keep: Sequence[bool] | None = None) -> np.ndarray:
    out = np.array([getattr(m, key) if m is not None else float("nan") for m in measures], dtype=np.float64)
    if keep is not None:
        out[~np.asarray(keep, dtype=bool)] = float("nan")
    return out


def summarise(sweep: PoseSweep, area_tolerance_mm2: float = 0.0) -> dict:
    """Within the training range: per measure ρ and slope of the model against the swept value, and
    for each reference kind (real frames, physics render) its own ρ and slope and the model's mean
    absolute error against it; the area's direction (the real frames' ρ where they have one, else
    the render's, else for Fz growing), the sign consistency of successive steps and whether the area
    is monotonic (ρ × that direction's sign ≥ MONOTONIC_RHO; |ρ| where there is no direction); for Fz
    the exponents k of area ∝ Fz^k. Beyond the training range: the area and the change away from the
    contact (a model that breaks down there shows stripes or blotches in the background)."""
    n = len(sweep.values)
    limited = np.array([bool(t) for t in sweep.notes] if len(sweep.notes) == n else [False] * n, dtype=bool)
    in_range = np.asarray(sweep.inside if sweep.inside else [True] * n, dtype=bool)
    inside, past = in_range & ~limited, ~in_range & ~limited  # the model's points: those it was conditioned at
    kinds = sweep.kinds if sweep.kinds else [REAL if m is not None else "" for m in sweep.reference]
    x = np.asarray(sweep.values, dtype=np.float64)
    xi = x[inside]
    out: dict = {
        "component": sweep.component,
        "pose": sweep.label,
        "run": sweep.run,
        "values": list(sweep.values),
        "inside_training_range": inside.tolist(),
        "sources": list(sweep.sources),
        "kinds": list(kinds),
        "model_area_mm2": _series(sweep.model, "area_mm2").tolist(),
        "range_note": sweep.range_note,
        "usable_points": int(inside.sum()),
        "last_inside_index": int(np.nonzero(inside)[0][-1]) if inside.any() else None,
    }
    if limited.any():  # left out of every measure below, and said
        out["render_limited_values"] = np.asarray(sweep.values)[limited].tolist()
        out["render_limited_note"] = next(t for t in sweep.notes if t)
    for kind, tag in KINDS.items():  # the references over the whole range: the same for every model
        is_kind = np.array([k == kind for k in kinds]) & in_range
        out[f"references_{tag}"] = int(is_kind.sum())
        out[f"{tag}_area_mm2"] = _series(sweep.reference, "area_mm2", is_kind).tolist()
    for key in MEASURES:
        m = _series(sweep.model, key)[inside]
        entry = {"rho": spearman(xi, m), "slope": slope(xi, m)}
        for kind, tag in KINDS.items():
            r = _series(sweep.reference, key, [k == kind for k in kinds])[inside]
            both = np.isfinite(m) & np.isfinite(r)
            entry[f"{tag}_rho"] = spearman(xi, r)
            entry[f"{tag}_slope"] = slope(xi, r)
            entry[f"{tag}_mae"] = float(np.mean(np.abs(m[both] - r[both]))) if both.any() else float("nan")
        out[key] = entry
    area = out["area_mm2"]
    direction, since = float("nan"), "no reference direction: |ρ|"
    for tag, words in (("real", "real frames"), ("render", "physics render")):
        if math.isfinite(area[f"{tag}_rho"]) and area[f"{tag}_rho"] != 0:
            direction, since = area[f"{tag}_rho"], words
            break
    if not math.isfinite(direction) and sweep.component == "Fz":
        direction, since = 1.0, "pressing harder never shrinks the contact"
    sign = float(np.sign(direction)) if math.isfinite(direction) else float("nan")
    model_area = _series(sweep.model, "area_mm2")
    out["direction"], out["direction_from"] = sign, since
    out["area_sign_consistency"] = sign_consistency(model_area[inside], sign, area_tolerance_mm2)
    rho = area["rho"]  # the sign of the direction, never its size: ρ × ρ_reference hid monotonic poses
    out["monotonic"] = bool(math.isfinite(rho) and (rho * sign if math.isfinite(sign) else abs(rho)) >= MONOTONIC_RHO)
    if sweep.component == "Fz":
        out["area_exponent"] = power_exponent(xi, model_area[inside])
        for tag in KINDS.values():
            r = np.asarray(out[f"{tag}_area_mm2"], dtype=np.float64)
            have = np.isfinite(r) & in_range  # an exponent through two points says nothing of its fit
            out[f"{tag}_area_exponent"] = power_exponent(x[have], r[have]) if have.sum() >= 3 else float("nan")
            both = have & inside
            out[f"area_exponent_at_{tag}"] = (
                power_exponent(x[both], model_area[both]) if both.sum() >= 3 else float("nan")
            )
    change = np.asarray(sweep.outside_change or [float("nan")] * n, dtype=np.float64)
    out["outside_change_in_range"] = _nanmean(change[inside])
    if past.any():
        out["beyond_values"] = x[past].tolist()
        out["beyond_area_mm2"] = model_area[past].tolist()
        out["outside_change_beyond"] = _nanmean(change[past])
    for kind, tag in KINDS.items():
        mses = [v for v, k, ok in zip(sweep.reference_mse, kinds, inside) if v is not None and k == kind and ok]
        out[f"image_mse_{tag}"] = float(np.mean(mses)) if mses else float("nan")
    return out


def grew_past_maximum(summary: dict) -> bool:
    """Whether the contact at the last value past the training maximum is larger than at the last value
    in range the model was conditioned at (a ``summarise`` dict with ``beyond_values``)."""
    last = summary.get("last_inside_index", sum(summary["inside_training_range"]) - 1)
    a, b = summary["beyond_area_mm2"][-1], None if last is None else summary["model_area_mm2"][last]
    return a is not None and b is not None and a > b


def _nanmean(v: np.ndarray) -> float:
    return float(np.mean(v[np.isfinite(v)])) if np.isfinite(v).any() else float("nan")


Generate = Callable[[int, np.ndarray], list[np.ndarray]]  # (pose index, raw wrenches (k, 6)) → k frames


def outside_change(image: np.ndarray, no_contact: np.ndarray, measure: ContactMeasure, blur_px: float) -> float:
    """Mean change (largest over channels, 0–255) from the no-contact frame farther than two contact
    radii from the contact's centroid (the whole frame without a contact): the background a model
    should leave alone."""
    from model.sweeps.sweep_measures import change_strength

    _, strength = change_strength(image, no_contact, blur_px)
    if measure.area_px == 0 or not math.isfinite(measure.centroid_x_mm):
        return float(strength.mean())
    h, w = strength.shape
    px = measure.area_mm2 / measure.area_px  # mm² per pixel
    cx = measure.centroid_x_mm / math.sqrt(px) + (w - 1) / 2
    cy = (h - 1) / 2 - measure.centroid_y_mm / math.sqrt(px)  # centroid y is +y up, rows run down
    rows, cols = np.mgrid[:h, :w]
    far = (cols - cx) ** 2 + (rows - cy) ** 2 > 4 * measure.area_px / math.pi
    return float(strength[far].mean()) if far.any() else float("nan")


def sweep_pose(
    generate: Generate,
    pose_index: int,
    component: str,
    values: np.ndarray,
    base_wrench: np.ndarray,
    *,
    no_contact: np.ndarray,
    mm_per_px: float,
    references: Sequence[Reference | tuple[np.ndarray | None, str]],
    label: str = "",
    run: str = "",
    inside: Sequence[bool] | None = None,
    threshold: float = THRESHOLD,
    blur_px: float = 1.0,
    notes: Callable[[], Sequence[str]] | None = None,
    range_note: str = "",
) -> PoseSweep:
    """Generate the sweep of ``component`` at one pose (the other components at ``base_wrench``),
    measure every frame and its reference (a ``Reference``, or (image, source) for a real frame).
    ``notes``: called after ``generate``, per value why the model's physics channels could not be
    rendered at it ("" where they were; such points are left out of every measure, and said)."""
    k = COMPONENTS[component]
    wrenches = np.repeat(np.asarray(base_wrench, dtype=np.float64)[None], len(values), axis=0)
    wrenches[:, k] = values
    images = generate(pose_index, wrenches)
    if len(images) != len(values):
        raise ValueError(f"the generator returned {len(images)} frames for {len(values)} wrenches")
    refs = [
        r if isinstance(r, Reference) else Reference(r[0], REAL if r[0] is not None else "", r[1]) for r in references
    ]

    def measure(img):
        return measure_contact(img, no_contact, mm_per_px=mm_per_px, threshold=threshold, blur_px=blur_px)

    model = [measure(img) for img in images]
    return PoseSweep(
        component,
        label,
        [float(v) for v in values],
        model,
        [measure(r.image) if r.image is not None else None for r in refs],
        [r.source for r in refs],
        [r.kind for r in refs],
        list(inside) if inside is not None else [True] * len(values),
        run,
        list(images),
        [r.image for r in refs],
        [
            float(np.mean((img.astype(np.float64) - r.image.astype(np.float64)) ** 2)) if r.image is not None else None
            for img, r in zip(images, refs)
        ],
        [outside_change(img, no_contact, m, blur_px) for img, m in zip(images, model)],
        list(notes()) if notes is not None else [],
        range_note,
    )


def sweep_values(low: float, high: float, points: int) -> np.ndarray:
    """``points`` evenly spaced values from ``low`` to ``high`` (the component's training range)."""
    if not (math.isfinite(low) and math.isfinite(high)) or points < 2:
        raise ValueError(f"a sweep needs a finite range and at least 2 points, got [{low}, {high}] × {points}")
    return np.linspace(low, high, points)


def beyond_values(low: float, high: float, fraction: float, points: int = 2) -> np.ndarray:
    """``points`` values past the training maximum, up to ``fraction`` of the range beyond it."""
    if fraction <= 0 or high <= low:
        return np.zeros(0)
    return high + (high - low) * fraction * np.arange(1, points + 1) / points


def run_force_sweep(
    generate: Generate,
    runs: dict[int, RunData],
    poses: list[tuple[int, int]],
    ranges: dict[str, tuple[float, float]],
    std: np.ndarray,
    *,
    points: int = 7,
    beyond: float = 0.0,
    physics: Physics | None = None,
    blur_px: float = 1.0,
    threshold: float = THRESHOLD,
    log: Callable[[str], None] = lambda line: None,
    clock: Callable[[], float] = time.perf_counter,
    notes: Callable[[], Sequence[str]] | None = None,
    skipped: dict[str, str] | None = None,
) -> list[PoseSweep]:
    """Every component of ``ranges`` swept at every pose (``generate(pose index, raw wrenches)``),
    each point beside its reference (model/sweeps/sweep_references.py); Fz also at two values up to
    ``beyond`` × its range past the training maximum (no reference there). At each pose the range
    is the training range within what the pose's own run recorded (``pose_range``): past that the
    run has no real frame and its render no depth to match, so a value there is not "in range".
    ``skipped`` gets why a component was not swept at a pose (swept at no pose: why not at all); a
    sweep at none of whose in-range values the model's channels could be rendered is left out, and
    said there too."""
    eta = Eta(len(poses) * len(ranges), clock)
    swept = tuple(COMPONENTS[name] for name in ranges)
    out: list[PoseSweep] = []
    why: dict[str, list[str]] = {name: [] for name in ranges}
    done = 0
    for p, (r, f) in enumerate(poses):
        run = runs[r]
        x, y, z, theta = (float(v) for v in run.pose[f])
        w = run.wrench[f]
        label = (
            f"{run.name} frame {f}: x {signed(x, 2)} y {signed(y, 2)} z {signed(z, 2)} mm θ {signed(theta, 1)}°, "
            f"Fz {signed(w[2], 2, '')} N Fx {signed(w[0], 2)} N Fy {signed(w[1], 2)} N Mz {signed(w[5], 1)} N·mm"
        )
        for name, split_range in ranges.items():
            low, high, range_note = pose_range(split_range, run.wrench[:, COMPONENTS[name]], name, run.name)
            if not high > low:
                why[name].append(f"{name} at pose {p + 1}: not swept ({range_note})")
                log(f"force sweep: {why[name][-1]}")
                continue
            values = sweep_values(low, high, points)
            refs = references_at(run, r, f, COMPONENTS[name], name, values, std, swept, physics)
            reaches_max = high >= split_range[1]  # past the training maximum only where the run reaches it
            extra = beyond_values(low, high, beyond) if name == "Fz" and reaches_max else np.zeros(0)
            swept_here = sweep_pose(
                generate,
                p,
                name,
                np.concatenate([values, extra]),
                w,
                no_contact=run.no_contact,
                mm_per_px=run.mm_per_px,
                references=refs + [NONE] * len(extra),
                label=label,
                run=run.name,
                inside=[True] * len(values) + [False] * len(extra),
                threshold=threshold,
                blur_px=blur_px,
                notes=notes,
                range_note=range_note,
            )
            usable = [not t for t, ok in zip(swept_here.notes, swept_here.inside) if ok]
            if swept_here.notes and not any(usable):
                reason = next(t for t in swept_here.notes if t)
                why[name].append(
                    f"{name} at pose {p + 1}: no value in range could be rendered for the model ({reason})"
                )
                log(f"force sweep: {why[name][-1]}")
            else:
                out.append(swept_here)
            done += 1
            log(f"force sweep: {name} at pose {p + 1}/{len(poses)}: {done}/{eta.total} sweeps, {eta.line(done)}")
    for name, reasons in why.items():
        if skipped is None or not reasons:
            continue
        if any(s.component == name for s in out):
            skipped.update({line.split(":")[0]: line for line in reasons})
        else:
            skipped[name] = f"{name}: swept at no pose (" + "; ".join(reasons) + ")"
    return out
