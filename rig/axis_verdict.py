"""What ``rig check-axes`` measured (rig/axis_check.py), judged: mirrored, swapped or turned axes,
the scale the camera sees, whether the gauge agrees, the fix, and the move that centres the contact.

Image vectors are in pixels with +x right and +y **up** (the run files' convention; an image's
rows run down, so a row index is negated). ``image_px_per_mm`` is the 2×2 matrix whose columns
are how far the contact moved in the image per mm of stage x and of stage y. A correct rig has
it close to s·I (s = 1 / mm_per_px). Any other signed permutation is a fixable mistake in the
config: which configured stage is x and which y, and each one's direction.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from rig.axis_check import Observation

ROTATION_LIMIT_DEG = 3.0  # the image turned more than this against the stages: turn the camera
SCALE_TOLERANCE = 0.10  # mm/px seen against the config's before it is reported
MIN_MOTION_PX = 1.0  # a step that moves the contact less than this in the image did not move it
MIN_SHEAR_N = 0.02  # a drag that changes Fx, Fy less than this (or 4σ) says nothing about the gauge
MIN_TWIST_NMM = 0.5  # the same for Mz between the two twists
AXES = ("x", "y")
IMAGE_AXES = ("right", "up")


@dataclass(frozen=True)
class AxisFix:
    """What the rig config must say so that the stages agree with the camera: for each of x and
    y, which configured stage it becomes and that stage's sign; θ's sign."""

    xy: tuple[tuple[str, int], tuple[str, int]] = (("x", 1), ("y", 1))  # new x, new y: (old axis, ±1)
    theta_sign: int = 1

    @property
    def needed(self) -> bool:
        return self.xy != (("x", 1), ("y", 1)) or self.theta_sign != 1

    @property
    def swapped(self) -> bool:
        return self.xy[0][0] != "x"

    def changes(self) -> list[str]:
        """One line per change, as the command prints them before writing."""
        out = []
        if self.swapped:
            out.append("x and y swapped: the stage configured as y becomes x, and x becomes y")
        for new, (_, sign) in zip(AXES, self.xy):
            if sign < 0:
                out.append(
                    f"{new} reversed (the {'stage now called ' + new if self.swapped else new} axis's "
                    "direction, offset and travel negated)"
                )
        if self.theta_sign < 0:
            out.append("theta reversed (its direction, offset and travel negated)")
        return out


@dataclass
class Verdict:
    image_px_per_mm: np.ndarray  # columns: stage x, y; rows: image right, up
    fix: AxisFix
    findings: list[str] = field(default_factory=list)  # what is wrong, one line each
    notes: list[str] = field(default_factory=list)  # what was measured, one line each
    mm_per_px_seen: float = math.nan
    rotation_deg: float = 0.0
    gauge: str = "not measured"  # "agrees with the camera", "disagrees…", "not measurable…"
    theta: str = "not checked"
    centre_offset_px: tuple[float, float] = (0.0, 0.0)  # contact − image centre: right, up
    centring_mm: dict[str, float] = field(default_factory=dict)  # the stage move that centres it

    @property
    def ok(self) -> bool:
        return not self.findings


def nearest_signed_permutation(m: np.ndarray) -> np.ndarray:
    """The 2×2 signed permutation P maximising trace(Pᵀ m): m's nearest axis assignment."""
    best, best_score = np.eye(2), -math.inf
    for perm in itertools.permutations(range(2)):
        for signs in itertools.product((1, -1), repeat=2):
            p = np.zeros((2, 2))
            for col, row in enumerate(perm):
                p[row, col] = signs[col]
            score = float(np.trace(p.T @ m))
            if score > best_score:
                best, best_score = p, score
    return best


def judge(seen: Observation, mm_per_px_config: float | None) -> Verdict:
    m = _image_matrix(seen)
    v = Verdict(m, AxisFix())
    moved = np.linalg.norm(m, axis=0) * seen.step_mm
    for name, px in zip(AXES, moved):
        if px < MIN_MOTION_PX:
            v.findings.append(
                f"stage {name} did not move the contact in the image ({px:.2f} px for ±{seen.step_mm:g} mm): "
                "is the stage moving, the camera looking at this gel?"
            )
    if seen.press_fz_N <= MIN_SHEAR_N:
        v.findings.append(
            f"pressing {seen.depth_mm:g} mm into the gel changed Fz by {seen.press_fz_N:+.3f} N: a press must read "
            "positive Fz (docs/hardware.md, Wiring)"
        )
    if v.findings:
        return v
    p = nearest_signed_permutation(m)
    v.fix = AxisFix(xy=_assignment(p))
    _describe_axes(v, m, p)
    _scale(v, m, seen, mm_per_px_config)
    _gauge(v, seen, p)
    _theta(v, seen)
    _centring(v, m, seen)
    return v


def _image_matrix(seen: Observation) -> np.ndarray:
    """Pixels per mm, image right/up (columns: stage x, y), from the presses at ±step (their shifts
    from the press at the start point)."""
    cols = []
    for axis in AXES:
        (c1, r1), (c2, r2) = seen.offset_px[(axis, 1)], seen.offset_px[(axis, -1)]
        cols.append([(c1 - c2) / (2 * seen.step_mm), -(r1 - r2) / (2 * seen.step_mm)])
    return np.array(cols).T


def _assignment(p: np.ndarray) -> tuple[tuple[str, int], tuple[str, int]]:
    """For new x and new y: the configured stage that moves the contact along image right / up,
    and whether its + goes that way."""
    out = []
    for row in range(2):
        col = int(np.flatnonzero(p[row])[0])
        out.append((AXES[col], int(p[row, col])))
    return out[0], out[1]


def _direction(vec: np.ndarray) -> str:
    right, up = vec
    if abs(right) >= abs(up):
        return "right" if right > 0 else "left"
    return "up" if up > 0 else "down"


def _describe_axes(v: Verdict, m: np.ndarray, p: np.ndarray) -> None:
    for col, name in enumerate(AXES):
        expected = IMAGE_AXES[col]
        seen_dir = _direction(m[:, col])
        line = f"stage +{name} moves the contact {seen_dir} in the image ({m[0, col]:+.2f}, {m[1, col]:+.2f} px/mm)"
        if seen_dir == expected:
            v.notes.append(line + ": as it should")
        else:
            v.findings.append(line + f": it should move it {expected}")
    corrected = m @ p.T  # the stages renamed and signed as the fix says: close to s·I
    v.rotation_deg = math.degrees(math.atan2(corrected[1, 0] - corrected[0, 1], corrected[0, 0] + corrected[1, 1]))
    if abs(v.rotation_deg) > ROTATION_LIMIT_DEG:
        v.findings.append(
            f"the image is turned {v.rotation_deg:+.1f}° against the stages (after any swap or reversal): "
            "turn the camera (or the sensor) until a move along x moves the contact along the image's rows"
        )
    else:
        v.notes.append(f"image turned {v.rotation_deg:+.1f}° against the stages (within ±{ROTATION_LIMIT_DEG:g}°)")


def _scale(v: Verdict, m: np.ndarray, seen: Observation, configured: float | None) -> None:
    px_per_mm = np.linalg.norm(m, axis=0)
    v.mm_per_px_seen = float(2 / px_per_mm.sum())
    if abs(px_per_mm[0] - px_per_mm[1]) > SCALE_TOLERANCE * px_per_mm.mean():
        v.findings.append(
            f"x and y move the contact by different amounts: {px_per_mm[0]:.2f} and {px_per_mm[1]:.2f} px/mm "
            "(a stage's scale in the config, or a camera looking at the gel at an angle)"
        )
    seen_text = f"{v.mm_per_px_seen:.5f} mm/px ({1 / v.mm_per_px_seen:.2f} px/mm)"
    if configured is None:
        v.notes.append(f"scale seen {seen_text}; [camera] mm_per_px is not set (run files record it): set it to this")
    elif abs(v.mm_per_px_seen / configured - 1) > SCALE_TOLERANCE:
        v.findings.append(
            f"scale seen {seen_text}, the config says mm_per_px = {configured:g} "
            f"({v.mm_per_px_seen / configured:.2f}x): check the stages' scale and [camera] mm_per_px"
        )
    else:
        v.notes.append(f"scale seen {seen_text}; the config says {configured:g} ({v.mm_per_px_seen / configured:.3f}x)")


def _gauge(v: Verdict, seen: Observation, p_image: np.ndarray) -> None:
    """Fx, Fy per mm of each stage's drag (columns): the same axis assignment as the image's?"""
    cols = []
    for axis in AXES:
        drags = [np.array(seen.shear_N[(axis, s)]) / (-s * seen.step_mm) for s in (1, -1)]
        cols.append((drags[0] + drags[1]) / 2)
    g = np.array(cols).T
    smallest = float(np.linalg.norm(g, axis=0).min() * seen.step_mm)
    threshold = max(MIN_SHEAR_N, 4 * seen.shear_noise_N)
    if smallest < threshold:
        v.gauge = f"not measurable: a {seen.step_mm:g} mm drag changed Fx/Fy by {smallest:.3f} N (< {threshold:.3f})"
        v.notes.append("gauge: " + v.gauge)
        return
    p_gauge = nearest_signed_permutation(g)
    if np.array_equal(p_gauge, p_image):
        v.gauge = "agrees with the camera"
        per_mm = np.linalg.norm(g, axis=0)
        v.notes.append(
            f"gauge: Fx, Fy follow the drags as the image does ({per_mm[0]:.2f} and {per_mm[1]:.2f} N per mm of "
            "stage x and y)"
        )
        return
    names = [f"{'+' if p_gauge[r, c] > 0 else '-'}F{'xy'[r]}" for c in range(2) for r in range(2) if p_gauge[r, c]]
    v.gauge = "disagrees with the camera"
    v.findings.append(
        f"gauge: a drag along +x reads as {names[0]}, along +y as {names[1]}, where the camera says otherwise: "
        "the gauge is mounted turned or mirrored against the camera (its axes are not the rig config's to fix)"
    )


def _theta(v: Verdict, seen: Observation) -> None:
    if not seen.twist_mz_Nmm:
        v.theta = "not checked (no theta axis)"
        return
    change = seen.twist_mz_Nmm[1] - seen.twist_mz_Nmm[-1]
    threshold = max(MIN_TWIST_NMM, 4 * seen.mz_noise_Nmm)
    if abs(change) < threshold:
        v.theta = (
            f"not measurable: Mz changed by {change:+.2f} N·mm between ±{seen.twist_deg:g}° (< {threshold:.2f}); "
            "a deeper press, a larger --twist-deg or a flat indenter shows it"
        )
    elif v.gauge != "agrees with the camera":
        v.theta = f"undetermined: Mz changed by {change:+.2f} N·mm, but the gauge's axes are not the camera's"
    elif change > 0:
        v.theta = (
            f"+theta turns counter-clockwise as the camera sees it (Mz {change:+.2f} N·mm over ±{seen.twist_deg:g}°)"
        )
    else:
        v.theta = f"+theta turns clockwise as the camera sees it (Mz {change:+.2f} N·mm over ±{seen.twist_deg:g}°)"
        v.findings.append("theta is reversed: " + v.theta + "; it should turn counter-clockwise")
        v.fix = AxisFix(xy=v.fix.xy, theta_sign=-1)
        return
    v.notes.append("theta: " + v.theta)


def _centring(v: Verdict, m: np.ndarray, seen: Observation) -> None:
    width, height = seen.frame_px
    cx, cy = seen.centre_px
    offset = np.array([cx - (width - 1) / 2, -(cy - (height - 1) / 2)])  # right, up
    v.centre_offset_px = (float(offset[0]), float(offset[1]))
    if abs(np.linalg.det(m)) < 1e-9:
        return
    move = np.linalg.solve(m, -offset)  # stage mm (as configured now) that bring the contact to the centre
    v.centring_mm = {"x": float(move[0]), "y": float(move[1])}
