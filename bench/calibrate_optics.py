"""Fit the shipped GelSight Mini sensor profile to the real presses (the real frames beside the checkout).

    .venv/bin/python bench/calibrate_optics.py [--data DIR]   # default: the real frames beside the checkout

Calls ``sensor_sim.calibration.fit_optics`` on the no-contact background and the
five ball presses (a ~4 mm steel ball: Taxim's calibration data), finding each contact
automatically (the published circles in presses.csv are printed beside them), and
writes sensor_sim/data/gelsight_mini.toml with its background gelsight_mini.png:
the real background cropped to the simulator's 14 mm square field of view.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import cv2

from sensor_sim.calibration import Press, fit_optics
from sensor_sim.profile import DEFAULT_PROFILE, SensorProfile, save_profile

MM_PER_PX = 0.0295  # as given by the data's publisher, approximate
BALL_RADIUS_MM = 2.0
CROP_MM = 14.0  # the square field of view the simulated sensor uses
FRAME_PX = 256
SOURCE = (
    "GelSight Mini frames from the Taxim calibration data (CMURoboTouch, MIT licence: "
    "LICENSE-gelsight-mini-data), as redistributed in the PyPI package taxim 1.4.1"
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data" / "gelsight_mini"
    )
    ap.add_argument("--out", type=Path, default=DEFAULT_PROFILE)
    args = ap.parse_args()
    background = cv2.imread(str(args.data / "background.png"), cv2.IMREAD_COLOR)
    rows = list(csv.DictReader(open(args.data / "presses.csv")))
    presses = [
        Press(cv2.imread(str(args.data / r["file"]), cv2.IMREAD_COLOR), BALL_RADIUS_MM, name=r["file"]) for r in rows
    ]
    t0 = time.perf_counter()
    fit = fit_optics(background, presses, MM_PER_PX)
    print(
        f"{len(presses)} presses from {args.data}: fitted in {time.perf_counter() - t0:.1f} s, "
        f"blur {fit.light.blur_mm:g} mm\n"
    )
    print(
        "| press | found centre x, y px | radius px | published centre | published touch radius | "
        "MAE whole | MAE within 1.5 radii |\n|---|---|---|---|---|---|---|"
    )
    for r, c, whole, near in zip(rows, fit.contacts, fit.press_mae, fit.press_mae_near):
        print(
            f"| {r['file']} | {c.centre_x_px:.1f}, {c.centre_y_px:.1f} | {c.radius_px:.1f} | "
            f"{r['touch_center_x_px']}, {r['touch_center_y_px']} | {r['touch_radius_px']} | "
            f"{whole:.2f} | {near:.2f} |"
        )
    h, w = background.shape[:2]
    side = int(round(CROP_MM / MM_PER_PX))
    y0, x0 = (h - side) // 2, (w - side) // 2
    profile = SensorProfile(
        name="gelsight_mini",
        source=SOURCE,
        width_px=FRAME_PX,
        height_px=FRAME_PX,
        mm_per_px=CROP_MM / FRAME_PX,
        gel_thickness_mm=3.0,
        gel_E_MPa=0.25,
        noise_std=1.0,
        light=fit.light,
        background=background[y0 : y0 + side, x0 : x0 + side],
    )
    print(f"\nwrote {save_profile(profile, args.out)} and its {side}x{side} background")


if __name__ == "__main__":
    main()
