"""Fit the simulated sensor's slope→colour response to real GelSight Mini presses.

    .venv/bin/python bench/calibrate_optics.py [--data ../shared/data/gelsight_mini]

The real frames are ball presses with known touch centre and radius (presses.csv).
Their surface is modelled as Hertz's half-space profile. The published "touch radius"
is the extent of the visible deformation, not the contact radius: the contact radius
is a fraction f of it, chosen by best fit like the optical blur σ. (The ball radius
only scales the slopes, which the fitted coefficients absorb; it is not identifiable.)
Per channel, the colour change is fitted as a quadratic in the surface slope.
Writes rig/sim/tactile/data/optics_calibration.json and the cropped background
gelsight_mini_background.png, and prints the fit's error table.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path

import cv2
import numpy as np

MM_PER_PX = 0.0295  # as given by the data's publisher, approximate
OUT = Path(__file__).resolve().parent.parent / "rig" / "sim" / "tactile" / "data"
CROP_MM = 14.0  # the square field of view the simulated sensor uses


def hertz_sink(r_mm: np.ndarray, a_mm: float, R_mm: float) -> np.ndarray:
    inside = (2 * a_mm**2 - r_mm**2) / (2 * R_mm)
    rr = np.maximum(r_mm, a_mm)
    outside = ((2 * a_mm**2 - rr**2) * np.arcsin(a_mm / rr) + a_mm * rr * np.sqrt(1 - (a_mm / rr) ** 2)) / (math.pi * R_mm)
    return np.where(r_mm <= a_mm, inside, outside)


def slope_features(sink_mm: np.ndarray, mm_per_px: float, blur_px: float) -> np.ndarray:
    """(H, W, 5): gx, gy, gx², gy², gx·gy of the surface height z = −sink (image axes)."""
    z = -sink_mm
    gy, gx = np.gradient(z, mm_per_px)
    if blur_px > 0:
        gx = cv2.GaussianBlur(gx, (0, 0), blur_px)
        gy = cv2.GaussianBlur(gy, (0, 0), blur_px)
    return np.stack([gx, gy, gx * gx, gy * gy, gx * gy], axis=-1)


def load_presses(folder: Path):
    background = cv2.imread(str(folder / "background.png")).astype(np.float64)
    presses = []
    with open(folder / "presses.csv") as f:
        for row in csv.DictReader(f):
            img = cv2.imread(str(folder / row["file"])).astype(np.float64)
            presses.append((img, float(row["touch_center_x_px"]), float(row["touch_center_y_px"]),
                            float(row["touch_radius_px"])))
    return background, presses


def design(background, presses, fraction, blur_px, R_mm=2.0):
    feats, targets = [], []
    h, w = background.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    for img, cx, cy, a_px in presses:
        r_mm = np.hypot(xx - cx, yy - cy) * MM_PER_PX
        a_mm = a_px * MM_PER_PX
        F = slope_features(hertz_sink(r_mm, fraction * a_mm, R_mm), MM_PER_PX, blur_px)
        region = r_mm < 3.5 * a_mm
        feats.append(F[region])
        targets.append((img - background)[region])
    return np.concatenate(feats), np.concatenate(targets)


def fit(background, presses, fraction, blur_px):
    A, B = design(background, presses, fraction, blur_px)
    coef, *_ = np.linalg.lstsq(A, B, rcond=None)  # (5, 3)
    resid = B - A @ coef
    return coef, float(np.sqrt(np.mean(resid**2))), float(np.sqrt(np.mean(B**2)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data" / "gelsight_mini")
    args = ap.parse_args()
    background, presses = load_presses(args.data)
    print(f"{len(presses)} presses from {args.data}\n")
    print("| contact / touch radius | blur σ px | RMS residual (0–255) | RMS signal | explained |\n|---|---|---|---|---|")
    best = None
    for fraction in (0.3, 0.4, 0.5, 0.6, 0.8, 1.0):
        for blur in (3.0, 6.0, 9.0):
            coef, rms, signal = fit(background, presses, fraction, blur)
            print(f"| {fraction:g} | {blur:g} | {rms:.2f} | {signal:.2f} | {1 - rms**2 / signal**2:.2f} |")
            if best is None or rms < best[2]:
                best = (fraction, blur, rms, signal, coef)
    fraction, blur, rms, signal, coef = best
    print(f"\nbest: contact radius = {fraction:g} × touch radius, blur σ = {blur:g} px ({blur * MM_PER_PX:.3f} mm): "
          f"RMS {rms:.2f} of {signal:.2f} ({1 - rms**2 / signal**2:.0%} of the variance explained)")
    OUT.mkdir(parents=True, exist_ok=True)
    calibration = {
        "source": "GelSight Mini presses from the Taxim calibration data (CMURoboTouch, MIT licence)",
        "features": ["gx", "gy", "gx^2", "gy^2", "gx*gy"],
        "feature_note": "surface slope of z = -sink in image axes (x right, y down), dimensionless",
        "coefficients_bgr": coef.T.tolist(),
        "blur_mm": blur * MM_PER_PX,
        "fit_contact_fraction_of_touch_radius": fraction,
        "rms_residual": rms,
        "rms_signal": signal,
    }
    (OUT / "optics_calibration.json").write_text(json.dumps(calibration, indent=2) + "\n")
    h, w = background.shape[:2]
    side = int(round(CROP_MM / MM_PER_PX))
    y0, x0 = (h - side) // 2, (w - side) // 2
    cv2.imwrite(str(OUT / "gelsight_mini_background.png"), background[y0:y0 + side, x0:x0 + side].astype(np.uint8))
    print(f"wrote {OUT / 'optics_calibration.json'} and the {side}x{side} background crop")


if __name__ == "__main__":
    main()
