"""Split a folder of GelSight presses into two press folders by region of the field.

    python docs/results/real-gelsight/regions/region_folders.py DATA OUT [--test-x-px 300:450]

DATA holds background.png, press_NN.png and presses.csv (the published contact centre of each
press, ``touch_center_x_px``). The presses whose published centre lies in the column band
``--test-x-px LOW:HIGH`` (pixels of the full frame, LOW inclusive) go to OUT/test/, the others (the
bands left and right of it) to OUT/train/; each a folder of the same form as DATA (background.png,
its presses and their rows of presses.csv), for gelsight_folder.py. A region is chosen by the
published centre, never by a frame's content, so that the split is fixed before anything is fitted.

One line naming the file or value for bad input; no traceback.
"""

from __future__ import annotations

import argparse
import csv
import math
import shutil
import sys
from pathlib import Path


def band(text: str) -> tuple[float, float]:
    try:
        low, high = (float(v) for v in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected LOW:HIGH in pixels, such as 300:450") from None
    if not (math.isfinite(low) and math.isfinite(high) and 0 <= low < high):
        raise argparse.ArgumentTypeError(f"{text!r}: expected finite 0 <= LOW < HIGH")
    return low, high


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("data", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--test-x-px", type=band, default=(300.0, 450.0))
    a = p.parse_args(argv)
    table = a.data / "presses.csv"
    try:
        with table.open(newline="") as fh:
            reader = csv.DictReader(fh)
            fields = list(reader.fieldnames or [])
            rows = list(reader)
        xs = [float(r["touch_center_x_px"]) for r in rows]
    except (OSError, KeyError, ValueError) as exc:
        print(f"error: {table}: needs file and touch_center_x_px columns of numbers ({exc})", file=sys.stderr)
        return 1
    if not all(math.isfinite(x) for x in xs):
        print(f"error: {table}: touch_center_x_px holds a value that is not a finite number", file=sys.stderr)
        return 1
    if a.out.exists():
        print(f"error: {a.out}: exists; give a new folder", file=sys.stderr)
        return 1
    low, high = a.test_x_px
    parts: dict[str, list[dict]] = {"train": [], "test": []}
    for row, x in zip(rows, xs):
        parts["test" if low <= x < high else "train"].append(row)
    if not parts["test"] or not parts["train"]:
        print(f"error: --test-x-px {low:g}:{high:g} leaves a region without presses", file=sys.stderr)
        return 1
    for name, chosen in parts.items():
        folder = a.out / name
        folder.mkdir(parents=True)
        shutil.copyfile(a.data / "background.png", folder / "background.png")
        for row in chosen:
            shutil.copyfile(a.data / row["file"], folder / row["file"])
        with (folder / "presses.csv").open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=fields)
            w.writeheader()
            w.writerows(chosen)
        files = ", ".join(r["file"].removesuffix(".png") for r in chosen)
        print(f"{folder}: {len(chosen)} presses ({files})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
