"""Contact sheet of the simulated sensor: three sensor kinds × indenters × depths.

    .venv/bin/python bench/contact_sheet.py [--out docs/img/contact_sheet.png]
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np

from rig.sim.contact import Pose
from rig.sim.tactile.indenters import get_indenter
from rig.sim.tactile.optics import SENSOR_KINDS
from rig.sim.tactile.scene import Scene

INDENTERS = ("sphere4mm", "sphere10mm", "sphere15mm", "circle8mm", "square", "ring", "heart", "woven", "irregular")
DEPTHS = (0.4, 1.2)
TILE = 128


def label(img: np.ndarray, text: str) -> np.ndarray:
    out = img.copy()
    cv2.putText(out, text, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="docs/img/contact_sheet.png")
    args = ap.parse_args()
    rows = [np.hstack([label(cv2.resize(get_indenter(n).object_image(256, 14.0 / 256), (TILE, TILE)), n)
                       for n in INDENTERS for _ in DEPTHS])]
    for kind in SENSOR_KINDS:
        tiles = []
        for name in INDENTERS:
            for depth in DEPTHS:
                scene = Scene(name, kind)
                # Press, then shear 0.5 mm in +x so that markers show their motion.
                scene.frame(Pose(0.0, 0.0, -depth, 0.0), image=False)
                frame = scene.frame(Pose(0.5, 0.0, -depth, 0.0))
                fz = frame.wrench[2]
                tiles.append(label(cv2.resize(frame.image, (TILE, TILE), interpolation=cv2.INTER_AREA),
                                   f"{kind} d={depth:g} Fz={fz:.1f}N"))
        rows.append(np.hstack(tiles))
    sheet = np.vstack(rows)
    cv2.imwrite(args.out, sheet)
    print(f"wrote {args.out} ({sheet.shape[1]}x{sheet.shape[0]}): rows = object image, "
          f"{', '.join(SENSOR_KINDS)}; columns = {', '.join(INDENTERS)} at depths {DEPTHS} mm, sheared +0.5 mm in x")


if __name__ == "__main__":
    main()
