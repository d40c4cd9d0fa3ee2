"""How many CPU threads torch uses: one per core that nothing else is using, from measurement.

Measured (docs/benchmarks.md, "Torch threads"): on a 2-core machine where other processes
keep the cores busy, torch's default of one thread per core trains 2.6–8× slower than one
thread and samples 1.6–4× slower (each step waits for the thread that shares a core). So
the count is the number of cores free now: the cores this process may run on, less the
other processes running at this moment (``/proc/stat``'s ``procs_running``, sampled a few
times, this process not counted); on an idle machine that is torch's own choice, all cores.

``--threads N`` on ``train``, ``generate`` and ``evaluate``, or ``TACTILE_TORCH_THREADS=N``,
overrides it. ``set_threads`` is the one place that sets it; it returns a line for the log.
"""

from __future__ import annotations

import os
import time
from typing import Callable, Mapping

ENV = "TACTILE_TORCH_THREADS"
MAX_THREADS = 256


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity), else the machine's count."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def running_now(
    samples: int = 5,
    read: Callable[[], str] | None = None,
    wait: Callable[[float], None] = time.sleep,
    interval_s: float = 0.02,
) -> float | None:
    """Processes running or ready to run now, this one included: the mean of ``samples`` reads
    of /proc/stat's procs_running, ``interval_s`` apart (``wait``: injected in tests); None where
    there is no /proc/stat."""
    values = []
    for k in range(samples):
        if k:
            wait(interval_s)
        try:
            text = read() if read is not None else _proc_stat()
        except OSError:
            return None
        line = next((ln for ln in text.splitlines() if ln.startswith("procs_running ")), None)
        if line is None:
            return None
        values.append(float(line.split()[1]))
    return sum(values) / len(values)


def _proc_stat() -> str:
    with open("/proc/stat") as fh:
        return fh.read()


def choose_threads(cores: int, running: float | None) -> int:
    """The rule: one thread per core left free by the other running processes (``running``
    counts this one), at least one, at most ``cores``; all cores when that is unknown."""
    if running is None:
        return max(1, cores)
    others = max(0.0, running - 1.0)
    return max(1, min(cores, int(cores - others + 0.5)))


def parse_override(value: str | int | None, where: str) -> int | None:
    """A thread count from a flag or the environment: a whole number 1–256, else a one-line ValueError."""
    if value is None or value == "":
        return None
    try:
        n = int(value)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: expected a whole number of threads 1–{MAX_THREADS}, got {value!r}") from None
    if not 1 <= n <= MAX_THREADS:
        raise ValueError(f"{where}: expected a whole number of threads 1–{MAX_THREADS}, got {value!r}")
    return n


def decide(flag: int | None, env: Mapping[str, str] | None = None, running: float | None = None) -> tuple[int, str]:
    """(threads, why): the flag, else the environment variable, else the rule."""
    n = parse_override(flag, "--threads")
    if n is not None:
        return n, "--threads"
    n = parse_override((os.environ if env is None else env).get(ENV), ENV)
    if n is not None:
        return n, ENV
    cores = usable_cores()
    running = running_now() if running is None else running
    busy = "unknown" if running is None else f"{max(0.0, running - 1):.1f}"
    return choose_threads(cores, running), f"{cores} core(s), {busy} other process(es) running"


def set_threads(flag: int | None = None) -> str:
    """Set torch's intra-op thread count (``decide``); the line saying what and why."""
    import torch

    n, why = decide(flag)
    torch.set_num_threads(n)
    return f"torch threads: {n} ({why})"
