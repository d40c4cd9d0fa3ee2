"""The console scripts' entry points (pyproject.toml, [project.scripts]): a Ctrl-C at any moment of a
command's start-up is one line, never a traceback nor a half-imported library's error.

``_run`` imports the command line itself, inside a handler of its own: a Ctrl-C that lands while a
module is being imported is held until that import has finished (it is looked at again every 20 ms),
then raised as KeyboardInterrupt, so that no library is left half imported (a Ctrl-C inside numpy's
import once came out as "AttributeError: module 'numpy._core' has no attribute '_multiarray_umath'").
A second Ctrl-C while the first is held ends the command at once. Anywhere else a Ctrl-C is raised
as usual, and the command's own handling applies (``friendly`` in cli/dataset_app.py, training's
checkpoint); a moving `rig` command keeps the hold it installed at its first instruction
(rig/early_signals.py). A KeyboardInterrupt that nothing took ends the process by SIGINT with one
line, as an uncaught Ctrl-C ends any program, so that a shell script running it stops too (a shell
goes on after a child that exited normally, even with status 130). The first milliseconds of Python's
own start-up, before any of this runs, are beyond reach.
"""

from __future__ import annotations

import importlib
import os
import signal
import sys

LOOK_AGAIN_S = 0.02  # how often a held Ctrl-C looks whether the import it landed in has finished
_held = False


def _in_import(frame) -> bool:
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def _die(message: str) -> None:
    sys.stderr.write(message + "\n")
    sys.stderr.flush()
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGINT)
    raise SystemExit(130)  # where SIGINT cannot end the process (a blocked mask)


def _on_sigint(_signum, frame) -> None:
    global _held
    if _held:
        _die("interrupted (Ctrl-C twice)")
    if _in_import(frame):
        _held = True
        signal.setitimer(signal.ITIMER_REAL, LOOK_AGAIN_S)
        return
    raise KeyboardInterrupt


def _on_alarm(_signum, frame) -> None:
    global _held
    if not _held:
        return
    if _in_import(frame):
        signal.setitimer(signal.ITIMER_REAL, LOOK_AGAIN_S)
        return
    _held = False
    raise KeyboardInterrupt


def _run(module: str, name: str) -> None:
    mine = signal.getsignal(signal.SIGINT) is signal.default_int_handler  # else a moving rig command's hold
    if mine:
        signal.signal(signal.SIGALRM, _on_alarm)
        signal.signal(signal.SIGINT, _on_sigint)
    try:
        getattr(importlib.import_module(module), name)()
    except KeyboardInterrupt:
        _die("interrupted (Ctrl-C)")
    finally:
        if mine:  # the command has ended: a Ctrl-C now (the interpreter's exit) only ends the process
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGINT, signal.SIG_DFL)
            if _held:  # it came during an import and the command ended before it could be raised
                _die("interrupted (Ctrl-C)")


def rig() -> None:
    _run("cli.rig_app", "app")


def dataset() -> None:
    _run("cli.dataset_app", "app")


def train() -> None:
    _run("cli.model_app", "main")


def generate() -> None:
    _run("cli.model_app", "generate_main")


def evaluate() -> None:
    _run("cli.model_app", "evaluate_main")


def compare() -> None:
    _run("cli.model_app", "compare_main")
