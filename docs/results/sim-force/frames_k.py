"""The simulated frames' own k of area ∝ Fz^k at ONE pose (the clean reference on simulated data).

Every frame of each run at the contact point's x, y (within 0.05 mm) and θ (within 0.2°) — the
press phases and the ends of the returns and untwists, so the depth (and Fz) varies and nothing
else does much — measured as the force sweep measures (model/sweeps/sweep_measures.measure_contact, the
same size, blur and threshold as the evaluation's report states), fitted in log–log over the frames
whose Fz lies in the training range (the split's 2nd–98th percentile). Also over all frames of the
part at their own poses, as `compare` reports it.

usage: python frames_k.py SPLIT SIZE BLUR THRESHOLD
"""

import json
import sys
from pathlib import Path

import numpy as np

from model.sweeps import sweep_measures as M
from model.sweeps.sweep_references import RunData

split, size, blur, threshold = Path(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
meta = json.loads((split / "split.json").read_text())
p2, p98 = meta["wrench_percentiles"]["p2"][2], meta["wrench_percentiles"]["p98"][2]
print(
    f"training range of Fz (2nd–98th percentile): {p2:.2f} – {p98:.2f} N; "
    f"size {size} px, blur {blur}, threshold {threshold}"
)
all_f, all_a = [], []
for run in meta["runs"]:
    data = RunData.load(run["path"], size)
    x, y, z, th = data.pose.T
    fz = data.wrench[:, 2]
    at = (np.abs(x) <= 0.05) & (np.abs(y) <= 0.05) & (np.abs(th) <= 0.2) & (fz > 0)
    inr = at & (fz >= p2) & (fz <= p98)
    areas = np.array(
        [
            M.measure_contact(
                data.frame(i), data.no_contact, mm_per_px=data.mm_per_px, threshold=threshold, blur_px=blur
            ).area_mm2
            for i in np.nonzero(at)[0]
        ]
    )
    f = fz[at]
    keep = (f >= p2) & (f <= p98)
    fe = M.frames_exponent(f[keep], areas[keep])
    print(
        f"{run['object']}: {at.sum()} frames at the contact point (x, y, θ ≈ 0), {inr.sum()} with Fz in range "
        f"({fe.fz_low:.2f}–{fe.fz_high:.2f} N; depth {z[inr].max():+.2f} … {z[inr].min():+.2f} mm): "
        f"k = {fe.k:+.3f} [{fe.low:+.3f}, {fe.high:+.3f}], ρ {fe.rho:+.2f}; over all {at.sum()} at the point "
        f"(Fz {f.min():.2f}–{f.max():.2f} N): k = {M.power_exponent(f, areas):+.3f}"
    )
    all_f += list(f[keep])
    all_a += list(areas[keep])
fe = M.frames_exponent(all_f, all_a)
print(f"both objects pooled, Fz in range: k = {fe.k:+.3f} [{fe.low:+.3f}, {fe.high:+.3f}] over {fe.frames} frames")
