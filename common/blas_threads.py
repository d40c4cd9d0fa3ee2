"""numpy's matrix products on the calling thread only (docs/simulator.md, "Threads and BLAS").

A rig command runs devices, their simulators and the camera on threads of one process, and several
of them call numpy's matrix products at the same time (the layer tables of the contact model, the
camera's noise). OpenBLAS's own thread pool, which numpy 2 bundles, has hung with concurrent
callers: two threads spinning for ever in its ``exec_blas`` and the process never ending after a
Ctrl-C (seen with OpenBLAS 0.3.31 under load). So every command runs BLAS single-threaded, which
costs nothing measurable here (the products are small; the work is FFTs and the threads are the
devices'). Standard library only: it runs before numpy is imported.
"""

from __future__ import annotations

import os
import sys

# the names OpenBLAS builds export for "use this many threads", numpy 2's (64-bit integer, prefixed) first
_SETTERS = (
    "scipy_openblas_set_num_threads64_",
    "scipy_openblas_set_num_threads",
    "openblas_set_num_threads64_",
    "openblas_set_num_threads",
)


def _loaded_openblas() -> list[str]:
    """Paths of the OpenBLAS libraries this process has loaded (Linux: /proc/self/maps)."""
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as maps:
            paths = {line.split()[-1] for line in maps if "openblas" in line.lower() and "/" in line}
    except OSError:
        return []
    return sorted(p for p in paths if p.startswith("/"))


def one_blas_thread() -> int:
    """BLAS on the calling thread from now on, in this process and the processes it starts.
    Before numpy is imported the environment does it; after, OpenBLAS's own call on each loaded
    copy. Returns how many loaded copies were told (0 when numpy is not loaded yet)."""
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    if "numpy" not in sys.modules:
        return 0
    import ctypes  # only here: the commands call this before numpy, and ctypes costs an import

    told = 0
    for path in _loaded_openblas():
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for name in _SETTERS:
            setter = getattr(lib, name, None)
            if setter is not None:
                setter(ctypes.c_int(1))
                told += 1
                break
    return told
