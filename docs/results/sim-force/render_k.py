"""The physics render's own k of area ∝ Fz^k at the contact point (x, y, θ = 0) of each run's object,
through the split's recorded sensor profile, measured as the force sweep measures (same size, blur,
threshold, the run's no-contact frame): (a) rendered at the depth where the simulator's contact
gives each of 7 Fz over the training range (what `physics_depth=force` conditions on) and over the
run's own Fz range; (b) at each of the run's own frames at the point, at the frame's measured z.

usage: python render_k.py SPLIT SIZE BLUR THRESHOLD
"""

import json
import sys
from pathlib import Path

import numpy as np

from model.conditioning.force_render import force_pose
from model.conditioning.physics_condition import resize, split_spec
from model.sweeps import sweep_measures as M
from model.sweeps.sweep_references import RunData

split, size, blur, threshold = Path(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
meta = json.loads((split / "split.json").read_text())
p2, p98 = meta["wrench_percentiles"]["p2"][2], meta["wrench_percentiles"]["p98"][2]
spec = split_spec(split)


def area(img, data):
    return M.measure_contact(img, data.no_contact, mm_per_px=data.mm_per_px, threshold=threshold, blur_px=blur).area_mm2


for run in meta["runs"]:
    data = RunData.load(run["path"], size)
    r = spec.renderer(run["object"], where=Path(run["path"]).name)
    fz_run = data.wrench[:, 2]
    for label, lo, hi in (("training range", p2, p98), ("the run's own range", p2, float(np.nanmax(fz_run)))):
        values = np.linspace(lo, hi, 7)
        areas = []
        for v in values:
            at, _ = force_pose(r, np.zeros(4), float(v))
            w = np.zeros(6)
            w[2] = v
            areas.append(area(resize(r.render(at, w), size), data))
        print(
            f"{run['object']}: render at the depth Fz implies, 7 Fz over {label} {lo:.2f}–{hi:.2f} N: "
            f"k = {M.power_exponent(values, areas):+.3f} (areas {', '.join(f'{a:.1f}' for a in areas)} mm²)"
        )
    x, y, z, th = data.pose.T
    at = np.nonzero((np.abs(x) <= 0.05) & (np.abs(y) <= 0.05) & (np.abs(th) <= 0.2) & (fz_run >= p2) & (fz_run <= p98))[
        0
    ]
    areas = [area(resize(r.render(data.pose[i], data.wrench[i]), size), data) for i in at]
    print(
        f"{run['object']}: render at each of its {len(at)} frames at the point (measured z), Fz in range: "
        f"k = {M.power_exponent(fz_run[at], areas):+.3f}"
    )
