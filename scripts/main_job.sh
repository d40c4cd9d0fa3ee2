#!/usr/bin/env bash
# The whole job on the built-in simulated rig, from nothing to a trained model and a report:
#   collect two objects → validate → split 8:2 → train (tiny preset, CPU) → evaluate.
# Every step is a command you can run yourself on your own rig (drop --sim, pass --config);
# each is printed before it runs ($ ...), and each stage prints the time so far and an estimate
# of the time left.
#
#   bash scripts/main_job.sh [OUT_DIR]        (default: jobs/main-YYYYmmdd-HHMMSS)
#
# Interrupted (Ctrl-C, a crash, a closed terminal)? The same command on the same folder continues:
# runs that finished and validate are kept, an interrupted run is resumed from the start of the
# level it broke (`rig run-protocol --resume`), a finished split is reused, training resumes from
# its last checkpoint (every 100 steps) and a finished report is kept. It refuses other knobs than
# the folder was started with (job.env).
#
# Knobs (environment), defaults chosen by bench/first_result_bench.py (docs/benchmarks.md,
# "The main job"): OBJECTS="sphere10mm circle8mm", SPEED_MM_S=0.1 (the paper's ~700 frames per
# object; the library default 0.01 mm/s gives ~5,800), COLLECT_PARALLEL=1 (collect the objects
# at the same time: each is one process; 0: one after another), STEPS=600 training steps,
# BATCH=16, LR=0.002, EVAL_FRAMES=150 test frames evaluated, SETTINGS=ddim:10,dpm:10,
# SWEEP_POSES=4 (evaluate's force sweep; its own default is 8),
# CONDITIONING=plane+embedding (the paper's wrench plane with an embedding, which these settings
# were measured with; `train`'s own default for rgb is physics, whose render cache adds about
# 40 ms per training frame: docs/model.md, "Conditioning").
# Before issue 17 the job trained 1,500 steps at LR=0.001 and evaluated 300 frames at
# ddim:10,ddim:25,dpm:10 (STEPS=1500 LR=0.001 EVAL_FRAMES=300 SETTINGS=ddim:10,ddim:25,dpm:10).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="$here/.venv/bin"
out="${1:-jobs/main-$(date +%Y%m%d-%H%M%S)}"
objects=(${OBJECTS:-sphere10mm circle8mm})
speed="${SPEED_MM_S:-0.1}"
parallel="${COLLECT_PARALLEL:-1}"
steps="${STEPS:-600}"
batch="${BATCH:-16}"
lr="${LR:-0.002}"
eval_frames="${EVAL_FRAMES:-150}"
settings="${SETTINGS:-ddim:10,dpm:10}"
conditioning="${CONDITIONING:-plane+embedding}"
# evaluate's force sweep at 4 poses spread over the field and the loads (its default, 8, takes about a
# minute more here: a first result, said in the report)
sweep_poses="${SWEEP_POSES:-4}"

if [[ ! -x "$bin/rig" ]]; then
    echo "error: $bin/rig not found: run 'bash scripts/setup.sh' first" >&2
    exit 2
fi
# the knobs a folder was started with: continuing it with others would mix two jobs
knobs="OBJECTS=${objects[*]} SPEED_MM_S=$speed STEPS=$steps BATCH=$batch LR=$lr EVAL_FRAMES=$eval_frames SETTINGS=$settings CONDITIONING=$conditioning SWEEP_POSES=$sweep_poses"
continuing=0
if [[ -e "$out" ]]; then
    if [[ ! -f "$out/job.env" ]]; then
        echo "error: $out exists and is not a main job's folder (no job.env): pass another output folder" >&2
        exit 2
    fi
    if [[ "$(cat "$out/job.env")" != "$knobs" ]]; then
        echo "error: $out was started with $(cat "$out/job.env"); continue it with the same knobs, or pass another folder" >&2
        exit 2
    fi
    continuing=1
fi
for knob in STEPS BATCH EVAL_FRAMES SWEEP_POSES; do
    value="${!knob:-1}"
    if ! [[ "$value" =~ ^[1-9][0-9]{0,6}$ ]]; then
        echo "error: $knob=$value: expected a whole number from 1 to 9999999" >&2
        exit 2
    fi
done
if [[ "$parallel" != 0 && "$parallel" != 1 ]]; then
    echo "error: COLLECT_PARALLEL=$parallel: expected 0 or 1" >&2
    exit 2
fi
mkdir -p "$out/runs"
[[ -f "$out/job.env" ]] || echo "$knobs" >"$out/job.env"
if ((continuing)); then
    echo "continuing $out (started with: $knobs)"
fi

# Seconds each stage takes with the defaults on an idle 2-core machine (docs/benchmarks.md, "The main
# job": 22 s, 1 s, 1 s, 2 min 20 s, 28 s; 3 min 12 s in all, against 2 min 31 s to 3 min 48 s measured
# there, sampling in bf16 where the CPU has it); the estimate scales them by the pace of the stages
# finished so far (common/eta.py).
nfe=0  # network evaluations per evaluated frame: the settings' step counts added up
IFS=, read -ra parts <<<"$settings"
for part in "${parts[@]}"; do
    [[ "${part#*:}" =~ ^[0-9]{1,4}$ ]] && nfe=$((nfe + ${part#*:}))
done
collect_s=$(( ((parallel)) && ((${#objects[@]} > 1)) ? 11 * ${#objects[@]} : 16 * ${#objects[@]} ))
expected="$collect_s,1,1,$(( 20 + steps * batch / 80 )),$(( 15 + eval_frames * nfe / 400 + eval_frames / 25 ))"
names=("collect ${#objects[@]} objects" "validate" "split" "train" "evaluate")
start=$SECONDS
i=0
took=()  # seconds each stage took, for the summary at the end
stage() {
    local left
    left="$("$bin/python" -m common.eta "$expected" "$i" "$((SECONDS - start))" 2>/dev/null || echo "time left unknown")"
    ((i > 0)) && took+=($((SECONDS - stage_start)))
    stage_start=$SECONDS
    i=$((i + 1))
    printf '\n\033[1m[%d/%d] %s\033[0m  (%s so far, %s)\n' "$i" "${#names[@]}" "$*" \
        "$(fmt $((SECONDS - start)))" "$left"
}
load() { cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo "?"; }
load_start="$(load)"
fmt() { if (($1 < 60)); then echo "$1 s"; else printf '%d min %02d s' $(($1 / 60)) $(($1 % 60)); fi; }
show() { printf '\033[2m$ %s\033[0m\n' "$*"; }
# A command stopped by Ctrl-C ends the job as `interrupted` says, whichever of the two hears the signal
# first: `rig run-protocol` exits 3 when interrupted (its run kept for --resume), the others 130. Under
# load bash could see the command's exit before its own SIGINT and end with that status instead.
run() {
    show "$@"
    local rc=0
    "$@" || rc=$?
    if ((rc == 130)) || { ((rc == 3)) && [[ "$2" == run-protocol ]]; }; then interrupted; fi
    return "$rc"
}

background=()
stop_background() { for pid in "${background[@]}"; do kill "$pid" 2>/dev/null || true; done; }
trap stop_background EXIT
interrupted() {
    stop_background
    printf '\ninterrupted: continue with\n  bash scripts/main_job.sh %q\n' "$out" >&2
    exit 130
}
trap interrupted INT TERM HUP

runs=()
stage "collect ${objects[*]} on the simulated rig: press/shear/twist at $speed mm/s, 1 Hz capture" \
    "$( ((parallel)) && ((${#objects[@]} > 1)) && echo '(at the same time; the last one shows its progress)')"
last=$(( ${#objects[@]} - 1 ))
for k in "${!objects[@]}"; do
    obj="${objects[$k]}"
    file="$out/runs/$obj.h5"
    runs+=("$file")
    if [[ -e "$file" ]] && "$bin/dataset" validate "$file" >/dev/null 2>&1; then
        echo "$file: complete and valid, kept"
        continue
    fi
    if [[ -e "$file" ]]; then  # interrupted: again from the start of the level it broke
        cmd=("$bin/rig" run-protocol "$obj" --sim --set "motion.speed_mm_s=$speed" --resume "$file")
    else
        cmd=("$bin/rig" run-protocol "$obj" --sim --set "motion.speed_mm_s=$speed" --out "$file")
    fi
    if ((parallel)) && ((k < last)); then
        show "${cmd[@]}" ">$out/runs/$obj.log 2>&1 &"
        "${cmd[@]}" >"$out/runs/$obj.log" 2>&1 &
        background+=($!)
    else
        run "${cmd[@]}"
    fi
done
for k in "${!background[@]}"; do
    if ! wait "${background[$k]}"; then
        echo "error: collecting ${objects[$k]} failed: see $out/runs/${objects[$k]}.log" >&2
        exit 1
    fi
    tail -n 3 "$out/runs/${objects[$k]}.log"
done
background=()

stage "validate the run files"
run "$bin/dataset" validate "${runs[@]}"

stage "split 8:2 by frame"
if [[ -f "$out/split/split.json" ]]; then
    echo "$out/split: made before, kept (train checks that its runs are unchanged)"
else
    run "$bin/dataset" split 8:2 "${runs[@]}" --out "$out/split"
fi

stage "train the tiny preset on CPU ($conditioning): $steps steps of $batch frames at learning rate $lr (validation samples in $out/model/samples)"
train=("$bin/train" --data "$out/split" --out "$out/model" --preset tiny --steps "$steps" --batch-size "$batch" --lr "$lr"
    --conditioning "$conditioning" --sample-every "$steps" --checkpoint-every 100)
done_steps="$("$bin/python" -c 'import json,sys; print(json.load(open(sys.argv[1]))["step"])' \
    "$out/model/checkpoint/state.json" 2>/dev/null || echo 0)"
if ((done_steps >= steps)); then
    echo "$out/model: trained to step $done_steps before, kept"
elif ((done_steps > 0)); then
    run "${train[@]}" --resume
else
    run "${train[@]}"
fi

stage "evaluate on up to $eval_frames held-out frames: $settings, and the physics render"
if [[ -f "$out/report/report.md" ]]; then
    echo "$out/report: written before, kept"
else
    run "$bin/evaluate" --checkpoint "$out/model" --split "$out/split" --out "$out/report" --settings "$settings" \
        --limit "$eval_frames" --sweep-poses "$sweep_poses"
fi

took+=($((SECONDS - stage_start)))
summary=""
for k in "${!names[@]}"; do
    summary+="${names[$k]} $(fmt "${took[$k]}"), "
done
printf '\n\033[1mdone in %s.\033[0m  report: %s\n' "$(fmt $((SECONDS - start)))" "$out/report/report.md"
printf 'stages: %s; load average %s at the start, %s at the end (%s cores)\n' "${summary%, }" "$load_start" \
    "$(load)" "$(nproc 2>/dev/null || echo ?)"
