"""A Ctrl-C at any moment of a command's start-up is one line, never a traceback of the project's code
(cli/entry.py).

Each command is interrupted at moments spread over its start-up (imports, Typer building the command
line, Click parsing it) and after: it ends by SIGINT with one line, or by its own handling, or finishes
as it would have. Before the entry point's first line runs, a Ctrl-C meets Python's own start-up
(importing its site module, then reading the entry module itself), which no code of the project runs
in: a traceback there is the only one allowed. A Ctrl-C inside a library's import can leave that
library half imported and come out as its error, in one line (seen once: numpy's "_multiarray_umath").
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent
ROOT = Path(__file__).resolve().parents[1]


def before_the_project(said: str) -> bool:
    """A traceback from before the entry point's first line: Python's site module, or the entry
    script's own `from cli.entry import ...` (nothing of the project has run)."""
    if "Fatal Python error: init_import_site" in said:
        return True
    frames = [line.strip() for line in said.splitlines() if line.strip().startswith("File ")]
    return said.count("Traceback") == 1 and frames[:1] != [] and all("/bin/" in f or "<frozen" in f for f in frames)


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
        if before_the_project(err):
            continue
        assert "Traceback" not in err, f"{command[0]} interrupted {at_s:.3f} s after its start: exit {rc}\n{err}"
        lines = err.strip().splitlines()
        if rc in (-signal.SIGINT, 130):  # interrupted: by SIGINT's default action, or its own handling
            # one line saying so, or nothing (before any handler), or its result already said (met its exit)
            assert not lines or lines[-1].startswith("interrupted") or "/nonexistent/" in err, err
        else:  # ended before the Ctrl-C (the error it gives for a missing file), or a library's import
            # interrupted surfaced as that library's error: in one line either way
            assert rc in (1, 2) and ("/nonexistent/" in err or (len(lines) == 1 and lines[0].startswith("error:"))), (
                rc,
                err,
            )
    interrupted = [line for line in said if f"exit {-signal.SIGINT}," in line or "exit 130," in line]
    assert interrupted, "\n".join(said)  # some Ctrl-C met the start-up


FINISHED = """
import sys, threading
sys.path.insert(0, sys.argv[1])
import cli.entry
cli.entry._run("finishing", "app")
"""
FINISHING = """
import sys, threading
def app():
    # a thread the interpreter joins as it shuts down, after the command has returned
    threading.Thread(target=threading.Event().wait, args=(30,)).start()
    print("done", flush=True)
"""


def test_a_ctrl_c_after_the_command_finished_ends_it_at_once_without_a_traceback(tmp_path):
    """The command returned; the interpreter joins a thread as it shuts down: a Ctrl-C then ends the
    process by SIGINT at once, not Python's "Exception ignored in: <module 'threading'>" traceback."""
    (tmp_path / "finishing.py").write_text(FINISHING)
    proc = subprocess.Popen(
        [sys.executable, "-c", FINISHED, str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout.readline().strip() == "done"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)  # not the thread's 30 s
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGINT, (proc.returncode, err)
    assert "Traceback" not in err and "Exception ignored" not in err, err


def test_a_ctrl_c_inside_a_held_block_is_raised_after_it_and_only_where_python_handles_ctrl_c():
    """``ctrl_c_after``: the block runs to its end (torch's import, where a Ctrl-C aborted the process),
    then KeyboardInterrupt; Python's handler is back; with SIGINT ignored the block runs as it is."""
    script = (
        "import signal, sys\n"
        "from cli.entry import ctrl_c_after\n"
        "if sys.argv[1] == 'ignored':\n"
        "    signal.signal(signal.SIGINT, signal.SIG_IGN)\n"
        "try:\n"
        "    with ctrl_c_after():\n"
        "        signal.raise_signal(signal.SIGINT)\n"
        "        sum(range(100000))  # bytecode on: a Ctrl-C not held would be raised here\n"
        "        print('block ended', flush=True)\n"
        "    print('nothing raised')\n"
        "except KeyboardInterrupt:\n"
        "    print('raised after it')\n"
        "print(signal.getsignal(signal.SIGINT) in (signal.default_int_handler, signal.SIG_IGN))\n"
    )
    for mode, said in (
        ("python", "block ended\nraised after it\nTrue\n"),
        ("ignored", "block ended\nnothing raised\nTrue\n"),
    ):
        done = subprocess.run(
            [sys.executable, "-c", script, mode], capture_output=True, text=True, cwd=ROOT, timeout=60
        )
        assert (done.returncode, done.stdout) == (0, said), done.stderr


def test_a_ctrl_c_while_the_cli_package_starts_is_its_one_line_and_sigint():
    """cli/__init__.py runs before cli/entry.py's first line: a Ctrl-C there (here raised by the BLAS set-up
    it calls) ends the process the same way, one line and SIGINT, not a traceback through the package."""
    script = (
        "import sys, types\n"
        "blas = types.ModuleType('common.blas_threads')\n"
        "def ctrl_c():\n"
        "    raise KeyboardInterrupt\n"
        "blas.one_blas_thread = ctrl_c\n"
        "sys.modules['common.blas_threads'] = blas\n"
        "import cli\n"
        "print('went on')\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert (done.returncode, done.stdout, done.stderr) == (-signal.SIGINT, "", "interrupted (Ctrl-C)\n")
