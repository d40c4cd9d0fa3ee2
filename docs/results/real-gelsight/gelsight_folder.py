"""Turn a folder of GelSight ball presses (background.png, press_NN.png, presses.csv) into the
folder `dataset import` reads (frames.csv, frames/, reference.png, object.png, run.json).

    python docs/results/real-gelsight/gelsight_folder.py DATA OUT [--ball-radius-mm 2.0] [--mm-per-px 0.0295]

The presses have no force gauge. Each press's contact is found in its frame (sensor_sim's
``find_contact``: the published centres sit a few pixels off, and published radii can be too
large); its depth and normal force are DERIVED from the found contact radius a by Hertz for a
sphere of radius R on a half-space of the gel's effective modulus E* = E / (1 − ν²) (E = 0.25 MPa,
ν = 0.48: the simulator's gel defaults, not measured on this sensor):

    depth d = a² / R,     Fz = 4 E* a³ / (3 R)

so Fz is a monotone function of the contact radius, and its absolute scale is only as good as E.
The pose is the found centre in mm from the image centre (+x right, +y up), z = −d, θ = 0; no
shear or twist is known: Fx, Fy, Mx, My, Mz are 0.

One line naming the file and the value for bad input; no traceback.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import shutil
import sys
from pathlib import Path

E_MPA, NU = 0.25, 0.48  # the simulator's gel defaults (sensor_sim/elastomer.py), not measured here


def hertz(radius_mm: float, ball_mm: float) -> tuple[float, float]:
    """(depth mm, Fz N) of a sphere of radius ``ball_mm`` whose contact radius is ``radius_mm``."""
    e_star = E_MPA / (1 - NU**2)
    return radius_mm**2 / ball_mm, 4 * e_star * radius_mm**3 / (3 * ball_mm)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("data", type=Path, help="folder with background.png, press_NN.png and presses.csv")
    p.add_argument("out", type=Path, help="new folder for `dataset import`")
    p.add_argument("--ball-radius-mm", type=float, default=2.0)
    p.add_argument("--mm-per-px", type=float, default=0.0295)
    p.add_argument("--profile-record", type=Path, default=None, help="unused: the import's --profile records it")
    a = p.parse_args(argv)

    import cv2

    from objects.indenters import INDENTERS
    from sensor_sim.contact_find import CalibrationError, find_contact

    table = a.data / "presses.csv"
    path = a.data / "background.png"
    background = cv2.imread(str(path)) if path.is_file() else None
    if background is None:
        print(f"error: {a.data / 'background.png'}: not a readable image", file=sys.stderr)
        return 1
    try:
        with table.open(newline="") as fh:
            files = [row["file"] for row in csv.DictReader(fh)]
    except (OSError, KeyError) as exc:
        print(f"error: {table}: needs a 'file' column ({exc})", file=sys.stderr)
        return 1
    if a.out.exists():
        print(f"error: {a.out}: exists; give a new folder", file=sys.stderr)
        return 1
    h, w = background.shape[:2]
    rows = []
    (a.out / "frames").mkdir(parents=True)
    for name in files:
        image = cv2.imread(str(a.data / name)) if (a.data / name).is_file() else None
        if image is None or image.shape != background.shape:
            print(f"error: {a.data / name}: not an image of the background's size {w}x{h}", file=sys.stderr)
            shutil.rmtree(a.out)
            return 1
        try:
            c = find_contact(background, image)
        except CalibrationError as exc:
            print(f"error: {a.data / name}: {exc}", file=sys.stderr)
            shutil.rmtree(a.out)
            return 1
        radius_mm = c.radius_px * a.mm_per_px
        depth, fz = hertz(radius_mm, a.ball_radius_mm)
        x = (c.centre_x_px - (w - 1) / 2) * a.mm_per_px
        y = ((h - 1) / 2 - c.centre_y_px) * a.mm_per_px
        shutil.copyfile(a.data / name, a.out / "frames" / name)
        rows.append((f"frames/{name}", fz, x, y, -depth, radius_mm))
    rows.sort(key=lambda r: r[1])  # by force: t_frame_s follows the row order
    with (a.out / "frames.csv").open("w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(
            ["file", "Fx_N", "Fy_N", "Fz_N", "Mx_Nmm", "My_Nmm", "Mz_Nmm", "x_mm", "y_mm", "z_mm", "theta_deg"]
        )
        for file, fz, x, y, z, _ in rows:
            out.writerow([file, 0.0, 0.0, round(fz, 5), 0.0, 0.0, 0.0, round(x, 4), round(y, 4), round(z, 4), 0.0])
    shutil.copyfile(a.data / "background.png", a.out / "reference.png")
    side = max(w, h)  # the object image spans the padded square field
    if not math.isclose(a.ball_radius_mm, 2.0):
        print(
            f"error: --ball-radius-mm {a.ball_radius_mm}: the object library has a 4 mm ball (2.0) only",
            file=sys.stderr,
        )
        return 1
    obj = INDENTERS["sphere4mm"]().object_image(side, a.mm_per_px)
    cv2.imwrite(str(a.out / "object.png"), obj)
    meta = {
        "mm_per_px": a.mm_per_px,
        "object": "sphere4mm",
        "protocol": "gelsight ball presses (Fz derived from the contact radius by Hertz)",
        "capture_hz": 1.0,
        "pose_convention": {
            "x": "right",
            "y": "up",
            "z": "negative_into_gel",
            "theta": "counter_clockwise",
            "origin": "contact_point",
        },
    }
    (a.out / "run.json").write_text(json.dumps(meta, indent=2) + "\n")
    fz = [r[1] for r in rows]
    radii = [r[5] for r in rows]
    print(
        f"{a.out}: {len(rows)} presses; contact radius {min(radii):.2f}–{max(radii):.2f} mm found in the frames; "
        f"Fz {min(fz):.2f}–{max(fz):.2f} N DERIVED by Hertz (E {E_MPA} MPa, ν {NU}, ball radius {a.ball_radius_mm} mm)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
