#!/usr/bin/env bash
# The model on real GelSight presses at the sizes users use, tested by region: trained on the presses of
# the field's outer column bands, tested on the presses of its central band (a run never trained on).
# Usage (from the repository root, .venv set up by scripts/setup.sh):
#
#   docs/results/real-gelsight/regions/run.sh DATA OUT [STEPS] [SEEDS_64] [SEEDS_128]
#
# DATA: the original GelSight presses (background.png, press_NN.png, presses.csv); OUT: a new folder.
# Fz is DERIVED from each press's contact radius by Hertz (no force gauge): ../gelsight_folder.py.
set -euo pipefail
DATA=${1:?usage: run.sh DATA OUT [STEPS] [SEEDS_64] [SEEDS_128]}
OUT=${2:?usage: run.sh DATA OUT [STEPS] [SEEDS_64] [SEEDS_128]}
STEPS=${3:-400}
SEEDS_64=${4:-0,1,2}
SEEDS_128=${5:-0}
HERE=$(cd "$(dirname "$0")" && pwd)
BIN=${BIN:-.venv/bin}
export OMP_NUM_THREADS=1
mkdir -p "$OUT"

# 1. two press folders by region: the central column band 300-450 px (9 presses) is the test run, the
#    bands left and right of it (15 presses) the training run
"$BIN/python" "$HERE/region_folders.py" "$DATA" "$OUT/data" --test-x-px 300:450
# 2. a sensor profile from five presses spread over the field, all of the training bands
"$BIN/rig" sensor calibrate "$OUT/data/train" --csv "$HERE/../calibration_presses.csv" --ball-radius-mm 2.0 \
    --mm-per-px 0.0295 --out "$OUT/profile/gelsight.toml" --name gelsight_original
# 3. each region as an import folder (contact found in each frame; depth and Fz by Hertz), imported with the
#    profile, padded square at 128 px
for part in train test; do
    "$BIN/python" "$HERE/../gelsight_folder.py" "$OUT/data/$part" "$OUT/folder-$part"
done
"$BIN/dataset" import "$OUT/folder-train" --out "$OUT/outer_bands.h5" --sensor rgb \
    --profile "$OUT/profile/gelsight.toml" --pad --size 128
"$BIN/dataset" import "$OUT/folder-test" --out "$OUT/central_band.h5" --sensor rgb \
    --profile "$OUT/profile/gelsight.toml" --pad --size 128
# 4. the split by run: central_band.h5 is the test part, never trained on
"$BIN/dataset" split 6:4 "$OUT/outer_bands.h5" "$OUT/central_band.h5" --test-runs central_band.h5 --out "$OUT/split"
# 5. the paper's plane and the gain-8 residual on the force-depth render, tiny preset, batches of 15 (the
#    training part's frames), STEPS steps; evaluated with DDIM 10, every baseline and the force sweep
CANDIDATES="--candidate plane
            --candidate physics,physics_depth=force,target=physics_residual,residual_gain=8"
# shellcheck disable=SC2086
"$BIN/compare" --data "$OUT/split" --out "$OUT/px64" $CANDIDATES --image-size 64 \
    --seeds "$SEEDS_64" --steps "$STEPS" --batch-size 15 --threads 1 --settings ddim:10
# shellcheck disable=SC2086
"$BIN/compare" --data "$OUT/split" --out "$OUT/px128" $CANDIDATES --image-size 128 \
    --seeds "$SEEDS_128" --steps "$STEPS" --batch-size 15 --threads 1 --settings ddim:10
echo "reports: $OUT/px64/compare.md $OUT/px128/compare.md"
