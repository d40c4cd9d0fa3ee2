"""How much of a board's texture a model of each resolution could show at best.

For each board run (a run file of `rig run-protocol woven|irregular|ridged`), every k-th
pressed frame is scored (model/evaluation/texture_measure.py, at the run's own resolution, inside the
contact) against the blurred-contact baseline at each model size — the real frame shrunk to
the model's resolution and back: the most texture a perfect model of that size can give.
A size whose pixel is more than half the board's shortest texture period cannot show the
texture and is said so, not scored. The table says which resolution to train at.

    .venv/bin/python bench/texture_ceiling.py RUN.h5 [RUN.h5 ...] [--every 20] [--sizes 32,64,128]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from acquisition.run_reader import RunReader  # noqa: E402
from common.machine import describe  # noqa: E402
from model.evaluation.texture_eval import blurred_contact, board_band, texture_rows  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--every", type=int, default=20, help="score every k-th pressed frame (default 20)")
    ap.add_argument("--sizes", default="32,64,128", help="model resolutions, px (default 32,64,128)")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    print(f"machine: {describe()}\n")
    print("| board | frames | model px | mm per model px | power ratio | spectrum corr | high-pass SSIM | score |")
    print("|---|---|---|---|---|---|---|---|")
    for path in args.runs:
        t0 = time.perf_counter()
        with RunReader.open(path) as run:
            name = run.text("object_name")
            mm_per_px = run.number("mm_per_px")
            background = run.image("reference_frame")
            levels = run.f["level"][()]
            pressed = np.nonzero(levels > 0)[0][:: args.every]
            real = [run.frame(int(i)) for i in pressed]
        width_mm = real[0].shape[1] * mm_per_px
        for size in sizes:
            band = board_band(name, width_mm / size)
            if band is None:
                print(f"| {name} | – | – | – | not a texture board | | | |")
                break
            # the band is resolved at the model's pixel; the score is taken at the run's own pixels
            if not band.resolved():
                cells = "not resolved: shortest period under 2 model px"
                print(f"| {name} | {len(real)} | {size} | {width_mm / size:.3f} | {cells} | | | |")
                continue
            made = [blurred_contact(r, size) for r in real]
            full = board_band(name, mm_per_px)
            assert full is not None
            rows = texture_rows(real, made, [background] * len(real), full)
            if isinstance(rows, str):
                print(f"| {name} | {len(real)} | {size} | {width_mm / size:.3f} | {rows} | | | |")
                continue
            cells = " | ".join(
                f"{rows[k][0]:.2f} [{rows[k][1]:.2f}, {rows[k][2]:.2f}]"
                for k in ("power_ratio", "spectrum_corr", "hp_ssim", "texture_score")
            )
            print(f"| {name} | {len(real)} | {size} | {width_mm / size:.3f} | {cells} |", flush=True)
        print(f"<!-- {name}: {time.perf_counter() - t0:.1f} s -->")


if __name__ == "__main__":
    main()
