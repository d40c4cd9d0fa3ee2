"""The type checker and the linter over the whole package, in CI through this test.

    python -m mypy common objects sensor_sim rig protocols acquisition dataset model cli
    python -m ruff check .
    python -m ruff format --check .

Settings live in pyproject.toml ([tool.mypy], [tool.ruff]). mypy also checks
tests/test_protocols_conform.py, whose assignments prove each driver satisfies its
protocol (rig/types.py). All three must report nothing.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("common", "objects", "sensor_sim", "rig", "protocols", "acquisition", "dataset", "model", "cli")


def run(*args: str) -> tuple[int, str]:
    done = subprocess.run([sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True, timeout=600)
    return done.returncode, done.stdout + done.stderr


@pytest.mark.slow
def test_mypy():
    rc, output = run("mypy", *PACKAGES, "tests/test_protocols_conform.py")
    assert rc == 0, "mypy:\n" + output


def test_ruff_lint():
    rc, output = run("ruff", "check", "--output-format", "concise", ".")
    assert rc == 0, "ruff check:\n" + output


def test_ruff_format():
    rc, output = run("ruff", "format", "--check", ".")
    assert rc == 0, "ruff format --check (run `ruff format .`):\n" + output
