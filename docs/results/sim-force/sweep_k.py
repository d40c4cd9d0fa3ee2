"""Per setting and seed, the Fz sweep's k of area ∝ Fz^k at each pose (from each run's report/metrics.json),
with the references' k at the same pose, and the mean over the poses whose run's own Fz reaches the
sweep's training maximum (the sweep range is the split's pooled 2nd–98th percentile, so at a pose of a
run whose frames never press that hard most of the "training range" is extrapolation for that object).

usage: python sweep_k.py COMPARE_DIR [SPLIT_DIR]
"""

import json
import math
import sys
from pathlib import Path

import numpy as np

root = Path(sys.argv[1])
own_max = {}
if len(sys.argv) > 2:
    from acquisition import schema as S
    from acquisition.run_reader import RunReader

    for run in json.loads((Path(sys.argv[2]) / "split.json").read_text())["runs"]:
        with RunReader.open(run["path"]) as f:
            own_max[Path(run["path"]).name] = float(np.nanmax(f.rows[S.WRENCH][:, 2]))


def f(v):
    return "—" if v is None or not math.isfinite(v) else f"{v:+.3f}"


out = {}
for cand in sorted(p for p in root.iterdir() if p.is_dir()):
    for seed in sorted(cand.glob("seed-*")):
        m = seed / "report" / "metrics.json"
        if not m.exists():
            continue
        part = json.loads(m.read_text())["parts"]["test"]
        fz = [s for s in part["force_sweep"] if s["component"] == "Fz"]
        full, within = [], []
        for i, s in enumerate(fz):
            inside = [v for v, ok in zip(s["values"], s["inside_training_range"]) if ok]
            top = own_max.get(s["run"], float("inf"))
            reaches = top >= 0.98 * max(inside)
            full.append(s["area_exponent"])
            if reaches:
                within.append(s["area_exponent"])
            below = "" if reaches else ", BELOW the sweep max " + format(max(inside), ".2f")
            real = f"{f(s.get('real_area_exponent'))} (model at those points {f(s.get('area_exponent_at_real'))})"
            rend = f"{f(s.get('render_area_exponent'))} (model at those points {f(s.get('area_exponent_at_render'))})"
            print(
                f"{cand.name} {seed.name} pose {i + 1} ({s['run']}, its own max Fz {top:.2f} N{below}): "
                f"model k {f(s['area_exponent'])}; real frames k {real}; render k {rend}"
            )
        out.setdefault(cand.name, []).append((np.mean(full), np.mean(within) if within else float("nan")))
print()
for name, ks in out.items():
    a = np.array(ks)
    sd_all = a[:, 0].std(ddof=1) if len(a) > 1 else float("nan")
    sd_reach = np.nanstd(a[:, 1], ddof=1) if len(a) > 1 else float("nan")
    print(
        f"{name}: per-seed mean k over all poses {', '.join(f'{v:+.3f}' for v in a[:, 0])} -> "
        f"{a[:, 0].mean():+.3f} ± {sd_all:.3f}; over poses whose run reaches the sweep max "
        f"{', '.join(f'{v:+.3f}' for v in a[:, 1])} -> {np.nanmean(a[:, 1]):+.3f} ± {sd_reach:.3f}"
    )
