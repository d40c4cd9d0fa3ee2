"""numpy's BLAS runs on the calling thread in every command (common/blas_threads.py): OpenBLAS's thread
pool hung with two threads of a simulated rig calling it at once, and the process never ended."""

from __future__ import annotations

import subprocess
import sys

# how many threads numpy's OpenBLAS would use, read through its own call
COUNT = """
import ctypes
from common.blas_threads import _loaded_openblas
counts = []
for path in _loaded_openblas():
    lib = ctypes.CDLL(path)
    for name in ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_", "openblas_get_num_threads"):
        getter = getattr(lib, name, None)
        if getter is not None:
            counts.append(getter())
            break
print(counts)
"""


def _threads(prelude: str) -> list[int]:
    code = prelude + "\nimport numpy\nimport numpy.linalg\n" + COUNT
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env={"PATH": "/usr/bin:/bin"}
    )
    assert done.returncode == 0, done.stderr
    return eval(done.stdout)  # a list of ints printed above


def test_a_plain_process_would_use_a_pool_so_the_check_can_fail():
    counts = _threads("import os; os.environ['OPENBLAS_NUM_THREADS'] = '2'")
    assert counts and max(counts) == 2


def test_every_command_runs_blas_on_the_calling_thread():
    counts = _threads("import os; os.environ['OPENBLAS_NUM_THREADS'] = '2'\nimport cli")
    assert counts and set(counts) == {1}


def test_told_after_numpy_loaded_too():
    prelude = (
        "import os; os.environ['OPENBLAS_NUM_THREADS'] = '2'\nimport numpy\n"
        "from common.blas_threads import one_blas_thread\nassert one_blas_thread() >= 1"
    )
    assert set(_threads(prelude)) == {1}
