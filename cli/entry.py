"""The console scripts' entry points (pyproject.toml, [project.scripts]).

Each imports its command line inside ``_run``, so that a Ctrl-C that nothing else took (during the
command's imports, while Typer builds the command line) ends it with one line, never a traceback.
Once a command runs, its own handling applies (``friendly`` in cli/dataset_app.py, the motion
session of a moving `rig` command, training's checkpoint). The process then ends by SIGINT, as an
uncaught Ctrl-C ends any program, so that a shell script running it stops too (a shell goes on after
a child that exited normally, even with status 130); so does a Ctrl-C after the command has finished,
while the interpreter shuts down; and so does one while cli/__init__.py runs, before this file's first
line. Not covered: Python's own start-up before that, and a Ctrl-C inside a library's import, which
can leave it half imported and come out as that library's error in one line (docs/safety.md); torch's
import, where a Ctrl-C aborted the process (pybind11's std::terminate, SIGABRT) or left torch half
imported, takes it only once torch is in (``ctrl_c_after``).
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import os
import signal
import sys
import threading

INTERRUPTED = "interrupted (Ctrl-C)"  # what a command says of a Ctrl-C that nothing else took


def die_by_sigint(message: str = INTERRUPTED) -> None:
    """Say ``message`` and end the process by SIGINT, as an uncaught Ctrl-C ends any program."""
    sys.stderr.write(message + "\n")
    sys.stderr.flush()
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGINT)
    raise SystemExit(130)  # where SIGINT cannot end the process (a blocked mask)


@contextlib.contextmanager
def ctrl_c_after():
    """A Ctrl-C inside the block is taken when the block has ended: KeyboardInterrupt raised here, after
    it (also in place of an error the block raised), never inside it (where it met C++ code that cannot
    pass it on). A second Ctrl-C while one is held ends the process at once (a hung import stays
    stoppable). Only where Python's own Ctrl-C handler is in place, on the main thread; elsewhere the
    block runs as it is. Python's handler is put back unless the block installed its own."""
    if threading.current_thread() is not threading.main_thread() or (
        signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield
        return
    said: list[int] = []

    def hold(signum, _frame) -> None:
        if said:
            die_by_sigint()
        said.append(signum)

    signal.signal(signal.SIGINT, hold)
    try:
        yield
    finally:
        if signal.getsignal(signal.SIGINT) is hold:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        if said:
            raise KeyboardInterrupt


def _run(module: str, name: str) -> None:
    try:
        getattr(importlib.import_module(module), name)()
    except KeyboardInterrupt:
        die_by_sigint()
    finally:
        if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
            # The command is done. A Ctrl-C while the interpreter shuts down (joining threads, exit
            # handlers) ends the process at once by SIGINT, instead of Python printing "Exception
            # ignored in: <module 'threading'>" and a KeyboardInterrupt traceback.
            signal.signal(signal.SIGINT, signal.SIG_DFL)


# one callable per console script (pyproject.toml names them)
rig = functools.partial(_run, "cli.rig_app", "app")
dataset = functools.partial(_run, "cli.dataset_app", "app")
train = functools.partial(_run, "cli.model_app", "main")
generate = functools.partial(_run, "cli.model_app", "generate_main")
evaluate = functools.partial(_run, "cli.model_app", "evaluate_main")
compare = functools.partial(_run, "cli.model_app", "compare_main")
