#!/usr/bin/env bash
# The force-response comparison on SIMULATED data (docs/results/sim-force/README.md), from the repository root:
#   bash docs/results/sim-force/run.sh OUT
# Two library objects on the simulated rig (rgb, 0.2 mm/s: 442 frames each), split 8:2 by frame, three
# settings x three seeds x 400 steps at 32 px (compare), then the frames' own and the render's k at one pose.
# About 45 min on 2 shared cores (one torch thread).
set -euo pipefail
out="${1:?usage: run.sh OUT}"
bin=.venv/bin
export OMP_NUM_THREADS=1
mkdir -p "$out/runs"
for obj in sphere10mm sphere4mm; do
    "$bin/rig" run-protocol "$obj" --sim --set motion.speed_mm_s=0.2 --set protocol.sensor=rgb --out "$out/runs/$obj.h5"
done
"$bin/dataset" validate "$out/runs/sphere10mm.h5" "$out/runs/sphere4mm.h5"
"$bin/dataset" split 8:2 "$out/runs/sphere10mm.h5" "$out/runs/sphere4mm.h5" --out "$out/split"
nice -n 5 "$bin/compare" --data "$out/split" --out "$out/compare" \
    --candidate plane --candidate physics,physics_depth=force \
    --candidate physics,physics_depth=force,target=physics_residual \
    --seeds 0,1,2 --steps 400 --threads 1 --settings ddim:10
# The references at one pose, measured as the sweep measures (32 px, blur 0.5 px, and the contact threshold
# each evaluation report states: 41.6 here, a third of the part's median peak change)
threshold="$(grep -o 'above [0-9.]* (0–255: a third' "$out/compare/plane/seed-0/report/report.md" | head -1 | cut -d' ' -f2)"
"$bin/python" docs/results/sim-force/frames_k.py "$out/split" 32 0.5 "$threshold"
"$bin/python" docs/results/sim-force/render_k.py "$out/split" 32 0.5 "$threshold"
"$bin/python" docs/results/sim-force/sweep_k.py "$out/compare" "$out/split"
