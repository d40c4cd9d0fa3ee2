"""A Ctrl-C at any moment of a command's start-up is one line, never a traceback (cli/entry.py).

Each command is interrupted at moments spread over its start-up (imports, Typer building the command
line, Click parsing it) and after: it ends by SIGINT with one line, or by its own handling, or finishes
as it would have. The first few milliseconds belong to Python's own start-up (importing its site
module), which no code of the project runs in: a traceback there says "Fatal Python error:
init_import_site" and is the only one allowed.
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent
INTERPRETER_START = "Fatal Python error: init_import_site"


def ours(stderr: str) -> int:
    """Tracebacks that come from a command's own code (not from Python's start-up before it)."""
    return stderr.count("Traceback") - stderr.count(INTERPRETER_START)


def interrupted_at(command: list[str], at_s: float) -> tuple[int, str]:
    proc = subprocess.Popen(
        [str(BIN / command[0]), *command[1:]], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    try:
        proc.wait(timeout=at_s)  # the moment, in real time after the start
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGINT)  # Ctrl-C
    said, _ = proc.communicate(timeout=120)
    return proc.returncode, said


@pytest.mark.slow
@pytest.mark.parametrize(
    "command, last_s",
    [
        (["dataset", "validate", "/nonexistent/run.h5"], 0.6),
        (["train", "--data", "/nonexistent/split", "--out", "/nonexistent/model"], 1.5),
        (["rig", "status", "--config", "/nonexistent/rig.toml"], 0.6),
    ],
    ids=["dataset", "train", "rig"],
)
def test_a_ctrl_c_during_start_up_is_one_line(command, last_s):
    said = []
    for k in range(10):
        at_s = last_s * k / 9
        rc, err = interrupted_at(command, at_s)
        said.append(f"at {at_s:.3f} s: exit {rc}, {err.strip().splitlines()[-1:] if err.strip() else 'nothing said'}")
        assert ours(err) == 0, f"{command[0]} interrupted {at_s:.3f} s after its start: exit {rc}\n{err}"
        if INTERPRETER_START in err:
            continue  # Python's own start-up met the Ctrl-C
        lines = err.strip().splitlines()
        if rc in (-signal.SIGINT, 130):  # interrupted: by SIGINT's default action, or its own handling
            # one line saying so, or nothing (before any handler), or its result already said (met its exit)
            assert not lines or lines[-1].startswith("interrupted") or "/nonexistent/" in err, err
        else:  # ended before the Ctrl-C: the error it gives for a missing file, in one line
            assert rc in (1, 2) and "/nonexistent/" in err, (rc, err)
    assert any("interrupted" in line for line in said), "\n".join(said)  # some Ctrl-C met the start-up
