"""Run files opened on one thread while another reads one (the console's run poller beside a command or
a test): HDF5 as h5py bundles it is not thread-safe, and h5py serialises its own calls with one lock;
acquisition/hdf5_open.py's bounded-read setter calls HDF5 around h5py (ctypes) and so must hold that
lock too. Without it this test's process segfaulted in 4 of 4 runs (HDF5's errors before that: "Can't
decrement id ref count", "no VOL object wrap context"), and a CI run's worker did."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HAMMER = """
import sys, threading, time
from pathlib import Path
import h5py, numpy as np
from acquisition.hdf5_open import _bounded_fapl, open_swmr_read
folder, seconds = Path(sys.argv[1]), float(sys.argv[2])
paths = [folder / f"run{i}.h5" for i in range(2)]
for p in paths:
    with h5py.File(p, "w", libver="latest") as f:
        for i in range(30):
            f.attrs[f"a{i}"] = np.arange(100)
stop = time.monotonic() + seconds
errors = []
def reader():
    try:
        while time.monotonic() < stop:
            with h5py.File(paths[0], "r") as f:
                for i in range(30):
                    f.attrs[f"a{i}"]
    except Exception as exc:
        errors.append(repr(exc))
threads = [threading.Thread(target=reader) for _ in range(2)]
for t in threads:
    t.start()
opened = 0
try:
    while time.monotonic() < stop:
        for _ in range(20):  # the property lists each open makes, where the setter runs
            _bounded_fapl(h5py.h5f.LIBVER_EARLIEST)
        with open_swmr_read(paths[1]) as f:
            f.attrs["a1"]
        opened += 1
except Exception as exc:
    errors.append(repr(exc))
for t in threads:
    t.join()
print(opened, errors)
"""


def test_opening_a_run_while_another_thread_reads_one_leaves_hdf5_whole(tmp_path):
    done = subprocess.run(
        [sys.executable, "-c", HAMMER, str(tmp_path), "4"], capture_output=True, text=True, timeout=120, cwd=ROOT
    )
    assert done.returncode == 0, done.stderr[-2000:]  # a segfault is -11
    opened, errors = done.stdout.split(" ", 1)
    assert int(opened) > 20 and errors.strip() == "[]", done.stdout
