#!/usr/bin/env bash
# The texture task on the simulated rig: the three texture boards pressed as the paper presses
# them (0.4 mm steps to 1.6 mm, shear, twist; at 0.1 mm/s, the paper's ~700 frames a board) ->
# split 8:2 by frame with the ridged board held out -> train the tiny preset at SIZE px with the
# paper's conditioning (object image + H(F) plane), one model per seed -> evaluate each on the
# test part (unseen frames of woven and irregular) and on test_object (the ridged board), with
# the texture measure beside MSE/SSIM. Usage (from the repository root):
#
#   docs/results/texture/run.sh OUT [SIZE] [STEPS] [SEEDS]
#
# Defaults as used for README.md: SIZE 64, STEPS 600, SEEDS "0 1", 120 evaluated frames a part.
set -euo pipefail
OUT=${1:?usage: run.sh OUT [SIZE] [STEPS] [SEEDS]}
SIZE=${2:-64}
STEPS=${3:-600}
SEEDS=${4:-0 1}
BIN=${BIN:-.venv/bin}
export OMP_NUM_THREADS=1
mkdir -p "$OUT"

# 1. the boards on the simulated rig (each ~15-40 s; their [limits] come from the protocol files)
for board in woven irregular ridged; do
    "$BIN/rig" run-protocol "$board" --sim --set motion.speed_mm_s=0.1 --out "$OUT/$board.h5"
done
# 2. what each model size could show at best (the blurred-contact ceiling)
"$BIN/python" bench/texture_ceiling.py "$OUT"/woven.h5 "$OUT"/irregular.h5 "$OUT"/ridged.h5 \
    --sizes 32,64,128,256 | tee "$OUT/ceiling.md"
# 3. split: 8:2 by frame over woven and irregular; every ridged frame in test_object
"$BIN/dataset" split 8:2 "$OUT"/woven.h5 "$OUT"/irregular.h5 "$OUT"/ridged.h5 --hold-out ridged --out "$OUT/split"
# 4. train and evaluate one model per seed
for seed in $SEEDS; do
    "$BIN/train" --data "$OUT/split" --out "$OUT/plane$SIZE-s$seed" --preset tiny --image-size "$SIZE" \
        --conditioning plane --steps "$STEPS" --threads 1 --seed "$seed"
    "$BIN/evaluate" --checkpoint "$OUT/plane$SIZE-s$seed" --split "$OUT/split" --out "$OUT/report-s$seed" \
        --settings ddim:10 --limit 120 --no-force-sweep
done
