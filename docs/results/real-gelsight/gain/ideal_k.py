"""What exponent would a perfect model of each assumption show? k of area ∝ Fz^k at every real press's
own place, with Fz swept over the training range, for three images that need no network:

- ``render``: the calibrated physics render at the depth each Fz implies (what the model is conditioned on);
- ``frame + render change``: the real frame plus the render's change from its own Fz — a model whose
  difference from the render does not depend on the load (a residual that ignores Fz);
- ``frame grown``: the real frame's contact scaled about the rendered contact by the square root of the
  rendered area ratio — what ``force_augment`` trains on (model/conditioning/force_augment.py).

    python docs/results/real-gelsight/gain/ideal_k.py SPLIT RUN THRESHOLD [--low 1.20 --high 1.76]

SPLIT: the split folder of run.sh (its profile renders); RUN: the imported run file (OUT/gelsight.h5);
THRESHOLD: the contact threshold the evaluation reports state (20.3 for the random split: a third of the
test part's median peak change). Measured as the force sweep measures: 32 px, change from the run's
no-contact frame (the no-load render for ``render``), blurred σ 0.5 px, above THRESHOLD.
"""

from __future__ import annotations

import argparse

import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader
from model.conditioning.force_augment import grown
from model.conditioning.force_render import render_at_force
from model.conditioning.physics_condition import resize, split_spec
from model.sweeps.sweep_measures import measure_contact, power_exponent

KINDS = ("render", "frame + render change", "frame grown")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("split")
    ap.add_argument("run")
    ap.add_argument("threshold", type=float)
    ap.add_argument("--low", type=float, default=1.20, help="training range of Fz, N (the sweep's)")
    ap.add_argument("--high", type=float, default=1.76)
    ap.add_argument("--size", type=int, default=32)
    args = ap.parse_args()
    size, blur = args.size, 0.5
    spec = split_spec(args.split)
    with RunReader.open(args.run) as f:
        poses, wrenches = f.rows[S.POSE_MEASURED], f.rows[S.WRENCH]
        reference = resize(f.image(S.REFERENCE_FRAME), size)
        frames = [resize(f.frame(i), size) for i in range(len(poses))]
        renderer = spec.renderer(f.text(S.ATTR_OBJECT))
    mm = spec.mm_per_px * spec.frame_px / size
    values = np.linspace(args.low, args.high, 7)
    k: dict[str, list[float]] = {kind: [] for kind in KINDS}
    for i in range(len(poses)):
        wrench, notes = np.asarray(wrenches[i], dtype=float), set()
        bare = render_at_force(renderer, poses[i], wrench, 0.0, size, notes)
        own = render_at_force(renderer, poses[i], wrench, float(wrench[2]), size, notes)
        area: dict[str, list[float]] = {kind: [] for kind in KINDS}
        for fz in values:
            render = render_at_force(renderer, poses[i], wrench, float(fz), size, notes)
            shifted = np.clip(frames[i].astype(int) + render.astype(int) - own.astype(int), 0, 255).astype(np.uint8)
            images = {
                "render": (render, bare),
                "frame + render change": (shifted, reference),
                "frame grown": (grown(frames[i], reference, own, render, bare), reference),
            }
            for kind, (image, base) in images.items():
                area[kind].append(
                    measure_contact(image, base, mm_per_px=mm, threshold=args.threshold, blur_px=blur).area_mm2
                )
        for kind in KINDS:
            k[kind].append(power_exponent(values, area[kind]))
    print(f"{len(poses)} presses, each at its own place; Fz swept {args.low:.2f}-{args.high:.2f} N, {size} px\n")
    print("| image | k, mean over the places | median | 10th-90th percentile |")
    print("|---|---|---|---|")
    for kind in KINDS:
        v = np.asarray(k[kind])
        lo, hi = np.nanpercentile(v, [10, 90])
        print(f"| {kind} | {np.nanmean(v):+.2f} | {np.nanmedian(v):+.2f} | {lo:+.2f} … {hi:+.2f} |")


if __name__ == "__main__":
    main()
