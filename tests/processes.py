"""Ending the processes a test started (`rig sim serve`, a console): Ctrl-C first, as a user
would, then kill after 30 s so that a hung one cannot hang the suite."""

from __future__ import annotations

import signal
import subprocess


def stop(proc: subprocess.Popen | None) -> None:
    if proc is None or proc.poll() is not None:
        return
    proc.send_signal(signal.SIGINT)
    try:
        proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
