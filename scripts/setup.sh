#!/usr/bin/env bash
# Create (or update) the project's virtual environment in .venv.
# torch is installed first and pinned, so that nothing later pulls a CUDA build.
# Each step says what it does and how long it took: a fresh set-up downloads several hundred MB
# (torch's CPU build is most of it) and takes minutes; one with nothing to do takes a second.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null 2>&1 || PY=python3
start=$SECONDS
step() { printf 'set-up: %s\n' "$*"; }
took() { printf 'set-up:   done (%d s)\n' $((SECONDS - $1)); }

if [ ! -x .venv/bin/python ]; then
    t=$SECONDS
    step "creating .venv with $("$PY" --version 2>&1)"
    "$PY" -m venv .venv
    took "$t"
fi
stamp=.venv/.installed-$(sha1sum pyproject.toml | cut -c1-12)
if [ ! -f "$stamp" ]; then
    t=$SECONDS
    step "updating pip"
    .venv/bin/python -m pip install -q --upgrade pip
    took "$t"
    t=$SECONDS
    step "installing torch 2.13.0, the CPU build (about 200 MB to download on a first set-up; pip is quiet meanwhile)"
    .venv/bin/python -m pip install -q torch==2.13.0
    took "$t"
    t=$SECONDS
    step "installing tactile-rig and its test and model extras (pyproject.toml: h5py, OpenCV, diffusers, selenium, ...)"
    .venv/bin/python -m pip install -q -e '.[dev,model]'
    took "$t"
    t=$SECONDS
    step "installing LeRobot's dataset reader, lerobot-dataset 0.4.4, without its pinned dependencies (the tests' reference reader)"
    # --no-deps: its pins would bring opencv-python-headless (a second OpenCV beside opencv-contrib-python-headless:
    # cv2 breaks), av<16 and huggingface_hub<0.36 (older than diffusers needs) and torchvision (built for another
    # torch). What it needs at run time is in the dev extra (datasets, pandas, torchcodec; av, pyarrow are the
    # project's own); torchvision is a stub in tests/lerobot_reader. `pip check` lists its unmet pins: expected.
    .venv/bin/python -m pip install -q --no-deps lerobot-dataset==0.4.4
    took "$t"
    rm -f .venv/.installed-*
    touch "$stamp"
else
    step ".venv is up to date with pyproject.toml: nothing to install"
fi

# The console's browser tests (tests/test_console.py) drive Debian's chromium through
# chromedriver. Installed here only as root (CI) where chromium is missing and apt-get
# exists; anyone else gets a note: install chromium and its driver yourself, or those
# tests skip (outside CI).
if ! command -v chromium >/dev/null 2>&1; then
    if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
        t=$SECONDS
        step "installing chromium and chromium-driver with apt-get (the web console's browser tests)"
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null
        took "$t"
    else
        echo "note: chromium and chromium-driver are not installed: the web console's browser tests will skip" >&2
    fi
fi
# The project's own modules compiled once: where Python may not write bytecode as it imports
# (PYTHONDONTWRITEBYTECODE, as on CI's machines) every command would compile them again at each start
# (rig's imports 0.6-0.7 s -> 0.46 s). Quick, and nothing when they are up to date.
.venv/bin/python -m compileall -q -j 0 acquisition cli common dataset model objects protocols rig sensor_sim ||
    echo "note: the project's modules were not all compiled ahead (above); they compile as they are imported" >&2
step "ready in $((SECONDS - start)) s: .venv/bin/rig, dataset, train, generate, evaluate, compare"
