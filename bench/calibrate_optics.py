"""Fit the shipped sensor profiles to the real presses (the real frames beside the checkout).

    .venv/bin/python bench/calibrate_optics.py [--sensor gelsight_mini|gelsight] [--data DIR] [--out TOML]

Calls ``sensor_sim.calibration.fit_optics`` on the no-contact background and the ball presses
(a ~4 mm steel ball: Taxim's calibration data), finding each contact automatically (the
published circles in presses.csv are printed beside them), measures the camera's noise
(``calibration_report.estimate_noise``) and writes the profile with its background beside it:

- ``gelsight_mini`` (the default): sensor_sim/data/gelsight_mini.toml from its five presses, the
  real background cropped to the simulator's 14 mm square field of view, rendered at 256 × 256
  (the simulated rig's frame and the model's image);
- ``gelsight``: sensor_sim/data/gelsight_original.toml from the 24 presses of an original
  GelSight spread over its field, the whole 640 × 480 frame at its own resolution (a sensor
  that is not square, with the light's change across the field).
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import cv2

from sensor_sim.calibration import Press, fit_optics
from sensor_sim.calibration_report import estimate_noise, profile_from_fit
from sensor_sim.elastomer import Elastomer
from sensor_sim.profile import DEFAULT_PROFILE
from sensor_sim.profile_save import save_profile

MM_PER_PX = 0.0295  # as given by the data's publisher, approximate
BALL_RADIUS_MM = 2.0
SOURCE = (
    "{what} frames from the Taxim calibration data (CMURoboTouch, MIT licence: LICENSE-gelsight-mini-data), "
    "as redistributed in the PyPI package taxim 1.4.1"
)
# name → (what the frames are, the profile written, the field (mm, None: the whole frame), frame width px)
SENSORS = {
    "gelsight_mini": ("GelSight Mini", DEFAULT_PROFILE, (14.0, 14.0), 256),
    "gelsight": ("Original GelSight", DEFAULT_PROFILE.with_name("gelsight_original.toml"), None, None),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sensor", choices=sorted(SENSORS), default="gelsight_mini")
    ap.add_argument("--data", type=Path, help="the frames (default: shared/data/SENSOR beside the checkout)")
    ap.add_argument("--out", type=Path, help="the profile to write (default: the shipped one)")
    args = ap.parse_args()
    what, shipped, field_mm, frame_px = SENSORS[args.sensor]
    data = args.data or Path(__file__).resolve().parents[2] / "shared" / "data" / args.sensor
    background = cv2.imread(str(data / "background.png"), cv2.IMREAD_COLOR)
    rows = list(csv.DictReader(open(data / "presses.csv")))
    presses = [Press(cv2.imread(str(data / r["file"]), cv2.IMREAD_COLOR), BALL_RADIUS_MM, name=r["file"]) for r in rows]
    gel = Elastomer()
    fit = fit_optics(background, presses, MM_PER_PX, gel=gel)
    noise = estimate_noise(background, presses, fit.contacts)
    print(f"{len(presses)} presses from {data}: fitted in {fit.seconds:.1f} s, blur {fit.light.blur_mm:g} mm")
    for note in fit.notes:
        print(f"note: {note}")
    print(
        f"light: position order {fit.order.order}; noise: std {noise.std_bgr} (b, g, r), correlation "
        f"{noise.correlation_px} px, between channels {noise.channel_correlation}\n"
    )
    print(
        "| press | found centre x, y px | radius px | depth mm | published centre | published touch radius |\n"
        "|---|---|---|---|---|---|"
    )
    for r, c in zip(rows, fit.contacts):
        print(
            f"| {r['file']} | {c.centre_x_px:.1f}, {c.centre_y_px:.1f} | {c.radius_px:.1f} | {c.depth_mm:.3f} | "
            f"{r['touch_center_x_px']}, {r['touch_center_y_px']} | {r['touch_radius_px']} |"
        )
    profile = profile_from_fit(
        background,
        fit,
        MM_PER_PX,
        name=shipped.stem,
        source=SOURCE.format(what=what),
        noise=noise,
        gel=gel,
        frame_width_px=frame_px,
        field_mm=field_mm,
    )
    print(
        f"\nwrote {save_profile(profile, args.out or shipped)} and its "
        f"{profile.background.shape[1]}x{profile.background.shape[0]} background"
    )


if __name__ == "__main__":
    main()
