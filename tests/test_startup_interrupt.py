"""A Ctrl-C at any moment of a command's start-up is one line, never a traceback (cli/entry.py).

Each command is interrupted at moments spread over its start-up (imports, Typer building the command
line, Click parsing it) and after, counted from its first instruction (cli/__init__.py, which makes
it catch SIGALRM): it ends by SIGINT with one line, or by its own handling, or finishes as it would
have. Before that instruction a Ctrl-C meets Python's own start-up, which no code of the project
runs in (docs/safety.md).
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent


def catches_sigalrm(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    caught = int(next(line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:")), 16)
    return bool(caught & (1 << (signal.SIGALRM - 1)))


def interrupted_at(command: list[str], at_s: float) -> tuple[int, str]:
    proc = subprocess.Popen(
        [str(BIN / command[0]), *command[1:]], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    for _ in range(15000):  # until its first instruction (bounded: 30 s)
        if catches_sigalrm(proc.pid):
            break
        try:
            proc.wait(timeout=0.002)
        except subprocess.TimeoutExpired:
            continue
        raise AssertionError(f"{command[0]} ended before its first instruction")
    try:
        proc.wait(timeout=at_s)  # the moment, in real time after the first instruction
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
        assert "Traceback" not in err, f"{command[0]} interrupted {at_s:.3f} s after its start: exit {rc}\n{err}"
        lines = err.strip().splitlines()
        if rc in (-signal.SIGINT, 130):  # interrupted: by SIGINT's default action, or its own handling
            # one line saying so, or nothing (before any handler), or its result already said (met its exit)
            assert not lines or lines[-1].startswith("interrupted") or "/nonexistent/" in err, err
        else:  # ended before the Ctrl-C: the error it gives for a missing file, in one line
            assert rc in (1, 2) and "/nonexistent/" in err, (rc, err)
    assert any("interrupted" in line for line in said), "\n".join(said)  # some Ctrl-C met the start-up
