"""Fit a sensor's optics (``LightModel``) to a no-contact frame and a few ball presses.

    result = fit_optics(background, [Press(img, ball_radius_mm=2.0), ...], mm_per_px=0.0295)
    result.light, result.contacts, result.press_mae

Each contact's centre and radius are found from the difference to the background
(``find_contact``) and refined by the fit itself, unless the press gives them. The
surface of a press is the ball's spherical cap inside the contact circle and the
gel's relaxation outside it (Hertz's half-space profile, scaled to meet the cap).
Per channel the colour change is a smooth lookup table over the surface normal
(``optics.LightModel``), linear in its entries, so the fit is a regularised least
squares; the optical blur is chosen by best fit from a few values. numpy/scipy/cv2 only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
import scipy.sparse as sp
from scipy.optimize import minimize
from scipy.sparse.linalg import spsolve

from sensor_sim.light import LightModel, normal_lookup

BLURS_MM = (0.1, 0.2, 0.3)  # optical blur candidates (leave-one-out on the GelSight Mini: 0.2 best)
TABLE_BINS = 21  # normal grid: 0.1 steps in nx, ny (17 and 25 fit the same, bench/optics_bench.py)
SMOOTHING = 1.0  # λ per 1000 fitted pixels; 0.1–10 change the held-out error by < 2 %
FIT_RADII = 3.0  # pixels within this many contact radii of a press enter the fit
# The visibly changed region reaches past the contact (the gel relaxes around it): the
# contact radius is 0.70–0.77 of the region's on synthetic presses, 0.65 on the
# real GelSight Mini ones after the fit. Radius and table trade off in the fit, so
# a good start matters.
RADIUS_OF_REGION = 0.75


class CalibrationError(ValueError):
    """Presses that cannot be fitted (no contact visible, wrong shapes, bad values)."""


@dataclass(frozen=True)
class Press:
    """One real press: a frame (BGR, the background's size) of a ball of known radius.

    ``centre_px`` (x, y) and ``radius_px`` override the contact found automatically;
    ``depth_mm`` (from the stage's z) sets the starting contact radius √(R·d) instead.
    """

    image: np.ndarray
    ball_radius_mm: float
    centre_px: tuple[float, float] | None = None
    radius_px: float | None = None
    depth_mm: float | None = None
    name: str = ""


@dataclass(frozen=True)
class Contact:
    centre_x_px: float
    centre_y_px: float
    radius_px: float


@dataclass
class CalibrationResult:
    light: LightModel
    contacts: list[Contact]
    press_mae: list[float] = field(default_factory=list)  # whole frame, 0–255
    press_mae_near: list[float] = field(default_factory=list)  # within 1.5 contact radii


def find_contact(background: np.ndarray, image: np.ndarray) -> Contact:
    """Centre and radius (px) of the pressed region: the centroid of where the colour
    differs from the background by more than a third of its peak, and the contact radius
    as RADIUS_OF_REGION × that region's equivalent radius (the refinement starts there)."""
    diff = np.abs(cv2.GaussianBlur(image.astype(np.float32) - background.astype(np.float32), (0, 0), 3.0)).sum(axis=2)
    peak = float(diff.max())
    if peak < 15.0:  # three channels of ~5 grey levels: noise and exposure drift, not a press
        raise CalibrationError(f"no contact visible: the frame differs from the background by at most {peak:.1f}")
    mask = (diff > peak / 3).astype(np.uint8)
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(mask)
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    weight = np.where(labels == k, diff, 0.0)
    ys, xs = np.mgrid[0 : diff.shape[0], 0 : diff.shape[1]]
    cx, cy = float((weight * xs).sum() / weight.sum()), float((weight * ys).sum() / weight.sum())
    return Contact(cx, cy, RADIUS_OF_REGION * math.sqrt(stats[k, cv2.CC_STAT_AREA] / math.pi))


def ball_height_mm(shape: tuple[int, int], contact: Contact, ball_radius_mm: float, mm_per_px: float) -> np.ndarray:
    """(H, W) gel surface height (mm, 0 = undeformed, negative = pressed in) for a ball press."""
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    r = np.hypot(xs - contact.centre_x_px, ys - contact.centre_y_px) * mm_per_px
    R = ball_radius_mm
    a = min(contact.radius_px * mm_per_px, 0.98 * R)
    # Outside: Hertz's half-space surface (contact radius a, curvature 1/R); its sink at
    # r = a is a²/2R. Inside: the spherical cap, lowered to meet it at the contact edge.
    rr = np.maximum(r, a)
    outside = ((2 * a * a - rr * rr) * np.arcsin(a / rr) + a * rr * np.sqrt(1 - (a / rr) ** 2)) / (math.pi * R)
    edge_sink = a * a / (2 * R)
    cap = np.sqrt(np.maximum(R * R - np.minimum(r, a) ** 2, 0.0)) - math.sqrt(R * R - a * a)
    return -np.where(r <= a, edge_sink + cap, outside)


def _window(contact: Contact, shape: tuple[int, int], radii: float, margin_px: int) -> tuple[slice, slice]:
    half = int(radii * contact.radius_px) + margin_px
    cx, cy = int(round(contact.centre_x_px)), int(round(contact.centre_y_px))
    return slice(max(cy - half, 0), min(cy + half, shape[0])), slice(max(cx - half, 0), min(cx + half, shape[1]))


def _local(contact: Contact, win: tuple[slice, slice]) -> Contact:
    return Contact(contact.centre_x_px - win[1].start, contact.centre_y_px - win[0].start, contact.radius_px)


def render_press(
    light: LightModel, background: np.ndarray, contact: Contact, ball_radius_mm: float, mm_per_px: float
) -> np.ndarray:
    """(H, W, 3) float frame of a ball press rendered over ``background`` (no noise, no bound)."""
    out = background.astype(np.float32).copy()
    win = _window(contact, background.shape[:2], 4.0, int(4 * light.blur_mm / mm_per_px) + 4)
    z = ball_height_mm(out[win].shape[:2], _local(contact, win), ball_radius_mm, mm_per_px)
    out[win] += light.change(*light.slopes(z, mm_per_px), out[win])
    return out


def _laplacian(bins: int) -> sp.csr_matrix:
    """Graph Laplacian of the bins × bins grid: penalises a table that is not smooth."""
    line = sp.diags([-np.ones(bins - 1), np.r_[1.0, 2 * np.ones(bins - 2), 1.0], -np.ones(bins - 1)], [-1, 0, 1])
    eye = sp.identity(bins)
    return (sp.kron(eye, line) + sp.kron(line, eye)).tocsr()


def fit_light(background, presses, contacts, mm_per_px, blur_mm, shading="multiplicative", bins=TABLE_BINS):
    """Least-squares LightModel for known contacts; returns (model, RMS residual).

    Per channel: min ‖A t − b‖² + λ‖L t‖² (L the grid Laplacian: normals the presses never
    showed get a smooth continuation), with the flat normal's entry held at 0.
    """
    mean_bgr = background.reshape(-1, 3).mean(axis=0)
    reference = (float(mean_bgr[0]), float(mean_bgr[1]), float(mean_bgr[2]))
    probe = LightModel(np.zeros((3, bins, bins), np.float32), float(blur_mm), shading, reference)
    idx_parts: list[np.ndarray] = []
    w_parts: list[np.ndarray] = []
    scale_parts: list[np.ndarray] = []
    target_parts: list[np.ndarray] = []
    for press, contact in zip(presses, contacts):
        win = _window(contact, background.shape[:2], FIT_RADII, int(4 * blur_mm / mm_per_px) + 4)
        local = _local(contact, win)
        bg = background[win].astype(np.float32)
        z = ball_height_mm(bg.shape[:2], local, press.ball_radius_mm, mm_per_px)
        ys, xs = np.mgrid[0 : bg.shape[0], 0 : bg.shape[1]]
        inside = np.hypot(xs - local.centre_x_px, ys - local.centre_y_px) < FIT_RADII * contact.radius_px
        i, wt = normal_lookup(*probe.slopes(z, mm_per_px), bins)
        idx_parts.append(i[inside])
        w_parts.append(wt[inside])
        scale_parts.append(
            bg[inside] / np.asarray(reference, np.float32)
            if shading == "multiplicative"
            else np.ones((int(inside.sum()), 3), np.float32)
        )
        target_parts.append((press.image[win].astype(np.float32) - bg)[inside])
    idx, w, scale, target = (np.concatenate(x) for x in (idx_parts, w_parts, scale_parts, target_parts))
    n = len(target)
    rows = np.repeat(np.arange(n), 4)
    lap = _laplacian(bins)
    keep = np.ones(bins * bins, bool)
    keep[(bins // 2) * bins + bins // 2] = False  # the flat gel shows the background: no change
    table = np.zeros((3, bins * bins))
    sq_err = 0.0
    for ch in range(3):
        A = sp.csr_matrix(((w * scale[:, ch : ch + 1]).ravel(), (rows, idx.ravel())), shape=(n, bins * bins))[:, keep]
        L = lap[:, keep]
        M = (A.T @ A + SMOOTHING * n / 1000.0 * (L.T @ L)).tocsc()
        t = spsolve(M, A.T @ target[:, ch])
        table[ch, keep] = t
        sq_err += float(np.sum((A @ t - target[:, ch]) ** 2))
    table = np.clip(table, -255, 255).reshape(3, bins, bins)
    return LightModel(table.astype(np.float32), float(blur_mm), shading, reference), math.sqrt(sq_err / (3 * n))


def _best_light(background, presses, contacts, mm_per_px, shading, blurs_mm):
    fits = [fit_light(background, presses, contacts, mm_per_px, b, shading) for b in blurs_mm]
    return min(fits, key=lambda fit: fit[1])[0]


def refine_contact(
    light: LightModel, background: np.ndarray, press: Press, contact: Contact, mm_per_px: float
) -> Contact:
    """The contact near ``contact`` whose rendering best matches the press under ``light``
    (Nelder–Mead on centre and radius, mean absolute error)."""
    win = _window(contact, background.shape[:2], FIT_RADII + 1, int(4 * light.blur_mm / mm_per_px) + 8)
    bg, real = background[win].astype(np.float32), press.image[win].astype(np.float32)
    x0, y0 = win[1].start, win[0].start

    def cost(p):
        c = Contact(p[0] - x0, p[1] - y0, max(p[2], 2.0))
        return float(np.mean(np.abs(render_press(light, bg, c, press.ball_radius_mm, mm_per_px) - real)))

    res = minimize(
        cost,
        [contact.centre_x_px, contact.centre_y_px, contact.radius_px],
        method="Nelder-Mead",
        options={"xatol": 0.2, "fatol": 1e-3, "maxiter": 100},
    )
    return Contact(float(res.x[0]), float(res.x[1]), float(max(res.x[2], 2.0)))


def _check(background: np.ndarray, presses: list[Press], mm_per_px: float) -> None:
    if background.ndim != 3 or background.shape[2] != 3:
        raise CalibrationError(f"background must be an H×W×3 colour frame, got shape {background.shape}")
    if not (math.isfinite(mm_per_px) and 0 < mm_per_px < 1):
        raise CalibrationError(f"mm_per_px must be in (0, 1) mm, got {mm_per_px}")
    if not presses:
        raise CalibrationError("no presses: at least one (three or more recommended) is needed")
    for i, p in enumerate(presses):
        name = p.name or f"press {i}"
        if p.image.shape != background.shape:
            raise CalibrationError(f"{name}: frame is {p.image.shape}, the background {background.shape}")
        if not (math.isfinite(p.ball_radius_mm) and p.ball_radius_mm > 0):
            raise CalibrationError(f"{name}: ball_radius_mm must be a finite number > 0, got {p.ball_radius_mm}")


def fit_optics(
    background: np.ndarray,
    presses: list[Press],
    mm_per_px: float,
    *,
    shading: str = "multiplicative",
    blurs_mm: tuple[float, ...] = BLURS_MM,
    refine: bool = True,
) -> CalibrationResult:
    """Fit a LightModel to ball presses over a no-contact ``background`` (BGR, H×W×3).

    Contacts not given are found automatically, then refined by rendering (``refine``).
    Raises CalibrationError (one line naming the press) for unusable input.
    """
    _check(background, presses, mm_per_px)
    contacts: list[Contact] = []
    for p in presses:
        if p.centre_px and p.radius_px:  # given in full: nothing to find
            contacts.append(Contact(float(p.centre_px[0]), float(p.centre_px[1]), float(p.radius_px)))
            continue
        found = find_contact(background, p.image)
        if p.depth_mm is not None and p.radius_px is None:
            found = Contact(found.centre_x_px, found.centre_y_px, math.sqrt(p.ball_radius_mm * p.depth_mm) / mm_per_px)
        cx, cy = p.centre_px or (found.centre_x_px, found.centre_y_px)
        contacts.append(Contact(float(cx), float(cy), float(p.radius_px or found.radius_px)))
    light = _best_light(background, presses, contacts, mm_per_px, shading, blurs_mm)
    if refine:
        for _ in range(2):  # contacts under the current light, then the light for those contacts
            contacts = [
                c if (p.centre_px and p.radius_px) else refine_contact(light, background, p, c, mm_per_px)
                for p, c in zip(presses, contacts)
            ]
            light = _best_light(background, presses, contacts, mm_per_px, shading, blurs_mm)
    result = CalibrationResult(light, contacts)
    for p, c in zip(presses, contacts):
        err = np.abs(render_press(light, background, c, p.ball_radius_mm, mm_per_px) - p.image.astype(np.float32))
        ys, xs = np.mgrid[0 : err.shape[0], 0 : err.shape[1]]
        near = np.hypot(xs - c.centre_x_px, ys - c.centre_y_px) < 1.5 * c.radius_px
        result.press_mae.append(float(err.mean()))
        result.press_mae_near.append(float(err[near].mean()))
    return result
