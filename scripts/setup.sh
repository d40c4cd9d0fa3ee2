#!/usr/bin/env bash
# Create (or update) the project's virtual environment in .venv.
# torch is installed first and pinned, so that nothing later pulls a CUDA build.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null 2>&1 || PY=python3
if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
fi
stamp=.venv/.installed-$(sha1sum pyproject.toml | cut -c1-12)
if [ ! -f "$stamp" ]; then
    .venv/bin/python -m pip install -q --upgrade pip
    .venv/bin/python -m pip install -q torch==2.13.0
    .venv/bin/python -m pip install -q -e '.[dev,model]'
    rm -f .venv/.installed-*
    touch "$stamp"
fi

# The console's browser tests (tests/test_console.py) drive Debian's chromium through
# chromedriver. Installed here only as root (CI) where chromium is missing and apt-get
# exists; anyone else gets a note: install chromium and its driver yourself, or those
# tests skip (outside CI).
if ! command -v chromium >/dev/null 2>&1; then
    if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null
    else
        echo "note: chromium and chromium-driver are not installed: the web console's browser tests will skip" >&2
    fi
fi
