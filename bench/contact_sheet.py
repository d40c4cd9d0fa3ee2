"""Contact sheet of the simulated sensor: three sensor kinds × indenters × depths.

    .venv/bin/python bench/contact_sheet.py [--out docs/img/contact_sheet.png] [--real DIR]

The last row sets real GelSight Mini presses of a ~4 mm ball (cropped to the simulator's
14 mm field of view) beside the simulated 4 mm sphere, when the real frames are there
(beside the checkout, or in --real DIR).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from objects.indenters import get_indenter
from objects.pose import Pose
from sensor_sim.light import SENSOR_KINDS
from sensor_sim.scene import Scene

INDENTERS = ("sphere4mm", "sphere10mm", "sphere15mm", "circle8mm", "square", "ring", "heart", "woven", "irregular")
DEPTHS = (0.4, 1.2)
TILE = 128
REAL_MM_PER_PX = 0.0295  # the real frames' scale, as given by their publisher


def real_row(folder: Path, width_px: int) -> np.ndarray | None:
    """Real presses, then the simulated 4 mm sphere (rgb) at three depths, on one row."""
    if not (folder / "background.png").exists():
        return None
    tiles = []
    for path in [folder / "background.png", *sorted(folder.glob("press_*.png"))]:
        img = cv2.imread(str(path), cv2.IMREAD_COLOR)
        h, w = img.shape[:2]
        side = int(round(14.0 / REAL_MM_PER_PX))
        crop = img[(h - side) // 2 : (h + side) // 2, (w - side) // 2 : (w + side) // 2]
        tiles.append(label(cv2.resize(crop, (TILE, TILE), interpolation=cv2.INTER_AREA), f"real {path.stem}"))
    for depth in (0.4, 0.8, 1.2, 1.6):
        frame = Scene("sphere4mm", "rgb").frame(Pose(0.0, 0.0, -depth, 0.0))
        tiles.append(
            label(cv2.resize(frame.image, (TILE, TILE), interpolation=cv2.INTER_AREA), f"sim sphere4mm d={depth:g}")
        )
    row = np.hstack(tiles)
    return np.hstack([row, np.zeros((TILE, width_px - row.shape[1], 3), np.uint8)])


def label(img: np.ndarray, text: str) -> np.ndarray:
    out = img.copy()
    cv2.putText(out, text, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="docs/img/contact_sheet.png")
    ap.add_argument(
        "--real", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data" / "gelsight_mini"
    )
    args = ap.parse_args()
    rows = [
        np.hstack(
            [
                label(cv2.resize(get_indenter(n).object_image(256, 14.0 / 256), (TILE, TILE)), n)
                for n in INDENTERS
                for _ in DEPTHS
            ]
        )
    ]
    for kind in SENSOR_KINDS:
        tiles = []
        for name in INDENTERS:
            for depth in DEPTHS:
                scene = Scene(name, kind)
                # Press, then shear 0.5 mm in +x so that markers show their motion.
                scene.frame(Pose(0.0, 0.0, -depth, 0.0), image=False)
                frame = scene.frame(Pose(0.5, 0.0, -depth, 0.0))
                fz = frame.wrench[2]
                tiles.append(
                    label(
                        cv2.resize(frame.image, (TILE, TILE), interpolation=cv2.INTER_AREA),
                        f"{kind} d={depth:g} Fz={fz:.1f}N",
                    )
                )
        rows.append(np.hstack(tiles))
    real = real_row(args.real, rows[0].shape[1])
    if real is not None:
        rows.append(real)
    sheet = np.vstack(rows)
    cv2.imwrite(args.out, sheet)
    print(
        f"wrote {args.out} ({sheet.shape[1]}x{sheet.shape[0]}): rows = object image, "
        f"{', '.join(SENSOR_KINDS)}; columns = {', '.join(INDENTERS)} at depths {DEPTHS} mm, sheared +0.5 mm in x"
        + ("; last row: real GelSight Mini frames beside the simulated 4 mm sphere" if real is not None else "")
    )


if __name__ == "__main__":
    main()
