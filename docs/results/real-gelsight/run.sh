#!/usr/bin/env bash
# The whole pipeline on real GelSight presses: calibrate -> import with the profile -> split ->
# train k seeds per setting -> evaluate -> compare.md, then the same on a split that holds out the
# five largest presses (held-out/compare.md). Usage (from the repository root, venv active
# or .venv present):
#
#   docs/results/real-gelsight/run.sh DATA OUT [STEPS] [SEEDS]
#
# DATA: a folder of presses (background.png, press_NN.png, presses.csv), e.g. the original
# GelSight set; OUT: a new working folder. STEPS (default 400) and SEEDS (default 0,1,2) as used
# for report.md. Fz is DERIVED from each press's contact radius by Hertz (no force gauge):
# see gelsight_folder.py.
set -euo pipefail
DATA=${1:?usage: run.sh DATA OUT [STEPS] [SEEDS]}
OUT=${2:?usage: run.sh DATA OUT [STEPS] [SEEDS]}
STEPS=${3:-400}
SEEDS=${4:-0,1,2}
HERE=$(cd "$(dirname "$0")" && pwd)
BIN=${BIN:-.venv/bin}
export OMP_NUM_THREADS=1
mkdir -p "$OUT"

# 1. a sensor profile from five presses spread over the field (they are in the data too: the physics
#    row is in-sample for any of them that lands in the test part; report.md names them)
"$BIN/rig" sensor calibrate "$DATA" --csv "$HERE/calibration_presses.csv" --ball-radius-mm 2.0 \
    --mm-per-px 0.0295 --out "$OUT/profile/gelsight.toml" --name gelsight_original
# 2. the presses as an import folder (contact found in each frame; depth and Fz by Hertz), imported
#    with the profile, padded square and brought to 128 px (mm per px 0.0295 * 640 / 128)
"$BIN/python" "$HERE/gelsight_folder.py" "$DATA" "$OUT/folder"
"$BIN/dataset" import "$OUT/folder" --out "$OUT/gelsight.h5" --sensor rgb \
    --profile "$OUT/profile/gelsight.toml" --pad --size 128
# 3. split 8:2 by frame
"$BIN/dataset" split 8:2 "$OUT/gelsight.h5" --out "$OUT/split"
# 4. five settings x SEEDS, tiny preset at 32 px, STEPS steps of 16, one torch thread;
#    each evaluated on the test part with DDIM 10, the force sweep and every baseline
"$BIN/compare" --data "$OUT/split" --out "$OUT/compare" \
    --candidate plane --candidate physics --candidate physics,physics_depth=force \
    --candidate physics,physics_depth=force,target=physics_residual \
    --candidate physics+embedding,physics_depth=force,target=physics_residual \
    --seeds "$SEEDS" --steps "$STEPS" --threads 1 --settings ddim:10
echo "report: $OUT/compare/compare.md"
# 5. the held-out split: the 5 presses of largest Fz (a press reads positive Fz; here 1.41-1.78 N) form
#    the part test_force, never trained on, and the other 19 are split 8:2 (15 training, 4 test
#    frames); three settings x SEEDS as in 4, but batches of 15: a batch may not exceed the 15
#    training frames. Evaluated on test and test_force, the force sweep over the training range
"$BIN/dataset" split 8:2 "$OUT/gelsight.h5" --out "$OUT/held-out/split" --hold-out-top Fz:5
"$BIN/compare" --data "$OUT/held-out/split" --out "$OUT/held-out/compare" \
    --candidate plane --candidate physics,physics_depth=force \
    --candidate physics,physics_depth=force,target=physics_residual \
    --seeds "$SEEDS" --steps "$STEPS" --batch-size 15 --threads 1 --settings ddim:10
echo "held-out report: $OUT/held-out/compare/compare.md"
# 6. the residual with gain 8 (residual_gain: the residual is multiplied by 8 before it is noised), with and
#    without force augmentation (force_augment 0.25: each frame also at Fz x 0.75 ... 1.25, its contact grown
#    as the render's), on both splits: gain/README.md
GAIN="--candidate physics,physics_depth=force,target=physics_residual,residual_gain=8
      --candidate physics,physics_depth=force,target=physics_residual,residual_gain=8,force_augment=0.25"
# shellcheck disable=SC2086
"$BIN/compare" --data "$OUT/split" --out "$OUT/gain" $GAIN \
    --seeds "$SEEDS" --steps "$STEPS" --threads 1 --settings ddim:10
# shellcheck disable=SC2086
"$BIN/compare" --data "$OUT/held-out/split" --out "$OUT/held-out/gain" $GAIN \
    --seeds "$SEEDS" --steps "$STEPS" --batch-size 15 --threads 1 --settings ddim:10
echo "gain reports: $OUT/gain/compare.md $OUT/held-out/gain/compare.md"
