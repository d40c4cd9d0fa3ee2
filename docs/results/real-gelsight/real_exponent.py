"""Can the real presses' own area-vs-Fz exponent be measured? Print k of area ∝ Fz^k across the real
frames for several contact-area measures and frame sizes, each with a 95 % bootstrap interval.

    python docs/results/real-gelsight/real_exponent.py FOLDER

FOLDER: the import folder `gelsight_folder.py` writes (frames.csv, frames/, reference.png). Its Fz
is DERIVED from each press's contact radius by Hertz, so the true exponent of the contact's area is
2/3 by construction (area ∝ a², Fz ∝ a³); what this prints is whether an area measured in the
frames, each at its own place in the field, recovers it. Frames are padded square and brought to
each size as `dataset import --pad --size` does (area interpolation). Measures, on the change from
the no-contact frame (the largest over channels, blurred σ 1 px, as the force sweep measures):

- ``sweep threshold``: above the sweep's threshold (a third of the median peak change, at least 8);
- ``half own peak``: above half of the frame's own peak change (brightness-normalised);
- ``second moment``: the change-weighted second moment about its centroid (sub-pixel);
- ``sum / peak``: the summed change over the peak change (an effective area).

Then, for the sweep's own measure, k fitted with the place in the field held fixed: log area on
log Fz beside the squared distance from the centre (and also x, y), by least squares, with a 95 %
bootstrap interval over the frames.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))

from model.sweeps.sweep_measures import change_strength, contact_threshold, frames_exponent  # noqa: E402

SIZES = (32, 64, 128)


def square(image: np.ndarray) -> np.ndarray:
    h, w = image.shape[:2]
    top, left = max(w - h, 0) // 2, max(h - w, 0) // 2
    return cv2.copyMakeBorder(image, top, max(w - h, 0) - top, left, max(h - w, 0) - left, cv2.BORDER_REPLICATE)


def measures(frame: np.ndarray, reference: np.ndarray, threshold: float) -> dict[str, float]:
    strength = change_strength(frame, reference, 1.0)[1]
    peak = float(strength.max())
    rows, cols = np.mgrid[0 : strength.shape[0], 0 : strength.shape[1]]
    weight = np.clip(strength - 0.25 * peak, 0, None)
    cx, cy = (weight * cols).sum() / weight.sum(), (weight * rows).sum() / weight.sum()
    return {
        "sweep threshold": float((strength > threshold).sum()),
        "half own peak": float((strength > 0.5 * peak).sum()),
        "second moment": float((weight * ((cols - cx) ** 2 + (rows - cy) ** 2)).sum() / weight.sum()),
        "sum / peak": float(strength.sum() / peak),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folder", type=Path, help="the import folder gelsight_folder.py wrote")
    a = p.parse_args(argv)
    table = a.folder / "frames.csv"
    reference = cv2.imread(str(a.folder / "reference.png"))
    if reference is None or not table.is_file():
        print(
            f"error: {a.folder}: expected frames.csv and reference.png (gelsight_folder.py's output)", file=sys.stderr
        )
        return 1
    rows = list(csv.DictReader(open(table)))
    fz = np.array([float(r["Fz_N"]) for r in rows])
    images = [cv2.imread(str(a.folder / r["file"])) for r in rows]
    print(f"{len(rows)} real frames, Fz {fz.min():.2f}-{fz.max():.2f} N (derived: true area exponent 2/3)\n")
    measured = {}  # size → each frame's measures at that size (both tables read them)
    for size in SIZES:
        ref = cv2.resize(square(reference), (size, size), interpolation=cv2.INTER_AREA)
        frames = [cv2.resize(square(f), (size, size), interpolation=cv2.INTER_AREA) for f in images]
        threshold = contact_threshold(frames, [ref] * len(frames), 1.0)[0]
        measured[size] = [measures(f, ref, threshold) for f in frames]
    print("| size px | measure | k | 95 % interval | Spearman rho |")
    print("|---|---|---|---|---|")
    for size, values in measured.items():
        for name in values[0]:
            e = frames_exponent(fz, [v[name] for v in values])
            print(f"| {size} | {name} | {e.k:+.2f} | [{e.low:+.2f}, {e.high:+.2f}] | {e.rho:+.2f} |")
    x = np.array([float(r["x_mm"]) for r in rows])
    y = np.array([float(r["y_mm"]) for r in rows])
    print("\n| size px | sweep threshold, place held fixed by | k | 95 % interval |")
    print("|---|---|---|---|")
    for size, values in measured.items():
        area = np.array([v["sweep threshold"] for v in values])
        for words, covariates in (
            ("distance² from the centre", [x**2 + y**2]),
            ("x, y, distance²", [x, y, x**2 + y**2]),
        ):
            k, low, high = controlled_exponent(fz, area, covariates)
            print(f"| {size} | {words} | {k:+.2f} | [{low:+.2f}, {high:+.2f}] |")
    return 0


def controlled_exponent(fz: np.ndarray, area: np.ndarray, covariates: list[np.ndarray], resamples: int = 2000):
    """(k, 2.5th, 97.5th percentile over bootstrap resamples of the frames): the coefficient of log Fz
    in a least-squares fit of log area on log Fz, a constant and ``covariates``."""
    keep = (fz > 0) & (area > 0)
    X = np.stack([np.log(fz[keep]), np.ones(keep.sum())] + [c[keep] for c in covariates], axis=1)
    y = np.log(area[keep])
    rng = np.random.default_rng(0)
    ks = [np.linalg.lstsq(X[i], y[i], rcond=None)[0][0] for i in rng.integers(0, len(y), (resamples, len(y)))]
    low, high = np.percentile(ks, [2.5, 97.5])
    return float(np.linalg.lstsq(X, y, rcond=None)[0][0]), float(low), float(high)


if __name__ == "__main__":
    raise SystemExit(main())
