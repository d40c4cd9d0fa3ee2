#!/usr/bin/env bash
# The whole job on the built-in simulated rig, from nothing to a trained model and a report:
#   collect two objects → validate → split 8:2 → train (tiny preset, CPU) → evaluate.
# Every step is a command you can run yourself on your own rig (drop --sim, pass --config).
#
#   bash scripts/main_job.sh [OUT_DIR]        (default: jobs/main-YYYYmmdd-HHMMSS)
#
# Knobs (environment): OBJECTS="sphere10mm circle8mm", SPEED_MM_S=0.1 (the paper's ~700
# frames per object; the library default 0.01 mm/s gives ~5,800), STEPS=1500 training steps,
# EVAL_FRAMES=300 test frames evaluated, SETTINGS=ddim:10,ddim:25,dpm:10.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="$here/.venv/bin"
out="${1:-jobs/main-$(date +%Y%m%d-%H%M%S)}"
objects=(${OBJECTS:-sphere10mm circle8mm})
speed="${SPEED_MM_S:-0.1}"
steps="${STEPS:-1500}"
eval_frames="${EVAL_FRAMES:-300}"
settings="${SETTINGS:-ddim:10,ddim:25,dpm:10}"

if [[ ! -x "$bin/rig" ]]; then
    echo "error: $bin/rig not found: run 'bash scripts/setup.sh' first" >&2
    exit 2
fi
if [[ -e "$out" ]]; then
    echo "error: $out exists: pass another output folder" >&2
    exit 2
fi
mkdir -p "$out/runs"
start=$SECONDS
n=$(( ${#objects[@]} + 4 ))
i=0
stage() { i=$((i + 1)); printf '\n\033[1m[%d/%d] %s\033[0m  (%ds so far)\n' "$i" "$n" "$*" "$((SECONDS - start))"; }

runs=()
for obj in "${objects[@]}"; do
    stage "collect $obj on the simulated rig: press/shear/twist at $speed mm/s, 1 Hz capture"
    "$bin/rig" run-protocol "$obj" --sim --set "motion.speed_mm_s=$speed" --out "$out/runs/$obj.h5"
    runs+=("$out/runs/$obj.h5")
done

stage "validate the run files"
"$bin/dataset" validate "${runs[@]}"

stage "split 8:2 by frame"
"$bin/dataset" split 8:2 "${runs[@]}" --out "$out/split"

stage "train the tiny preset on CPU for $steps steps (validation samples in $out/model/samples)"
"$bin/train" --data "$out/split" --out "$out/model" --preset tiny --steps "$steps" --sample-every 500

stage "evaluate on up to $eval_frames held-out frames: $settings, and the physics render"
"$bin/evaluate" --checkpoint "$out/model" --split "$out/split" --out "$out/report" --settings "$settings" \
    --limit "$eval_frames"

printf '\n\033[1mdone in %dm%02ds.\033[0m  report: %s\n' "$(((SECONDS - start) / 60))" "$(((SECONDS - start) % 60))" \
    "$out/report/report.md"
