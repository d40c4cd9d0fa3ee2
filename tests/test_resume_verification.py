"""``--resume`` verifies what validate verifies, read-only and bounded, before it appends a frame.

Before: a damaged chunk index kept `--resume` asleep in HDF5's metadata retries until kill -9 (SIGTERM
was ignored); the object image, the reference frame and the checksum filters went unchecked; and a
crashed run's stream lost every row after its first damaged chunk, sound chunks after it included.
The CLI cases of a crashed run: tests/test_corruption_corpus.py.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from test_verified_reads import chunk_index_byte, chunk_middle, flip, write_run

from acquisition import schema as S
from acquisition.run_file import RunFileError, RunWriter

ROOT = Path(__file__).resolve().parents[1]

REOPEN = """
import sys
from acquisition.run_file import RunFileError, RunWriter
try:
    RunWriter.reopen(sys.argv[1]).close()
except RunFileError as exc:
    print(exc)
else:
    print("resumed")
"""


@pytest.mark.parametrize("closed", [True, False], ids=["closed", "crashed"])
def test_a_damaged_chunk_index_is_refused_within_seconds(tmp_path, closed):
    """In its own process, under a deadline: before, it never returned."""
    path = write_run(tmp_path / "run.h5", close=closed)
    flip(path, chunk_index_byte(path, S.FRAMES))
    out = subprocess.run(
        [sys.executable, "-c", REOPEN, str(path)], capture_output=True, text=True, timeout=60, cwd=ROOT
    )
    line = out.stdout.strip()
    assert line.startswith(f"{path}: frames: chunk index unreadable") and line.endswith("cannot resume it"), out
    assert not list(tmp_path.glob("*.lock"))


def test_a_damaged_image_is_refused(tmp_path):
    for name in (S.OBJECT_IMAGE, S.REFERENCE_FRAME):
        path = write_run(tmp_path / f"{name.replace('/', '-')}.h5", close=False)
        flip(path, chunk_middle(path, name, 0))
        with pytest.raises(RunFileError, match=rf"^{path}: {name}: unreadable.*cannot resume it"):
            RunWriter.reopen(path)
    assert not list(tmp_path.glob("*.lock"))


def test_a_dataset_without_the_checksum_filter_is_refused(tmp_path):
    path = write_run(tmp_path / "run.h5", close=False)
    with h5py.File(path, "r+") as f:  # one row dataset rewritten without Fletcher-32
        data = f[S.STEP_INDEX][()]
        del f[S.STEP_INDEX]
        f.create_dataset(S.STEP_INDEX, data=data, maxshape=(None,), chunks=(256,))
    with pytest.raises(RunFileError, match=rf"^{path}: step_index: no checksum filter.*cannot resume it"):
        RunWriter.reopen(path)


def test_a_crashed_runs_stream_keeps_its_sound_rows_and_drops_only_its_unwritten_tail(tmp_path):
    """60 stream rows a frame, 20 frames: two stream chunks (1,024 rows each)."""
    tail = write_run(tmp_path / "tail.h5", close=False, samples=60, n=20)
    with h5py.File(tail, "r") as f:
        stream = f[S.WRENCH_STREAM][()]
    with h5py.File(tail, "r+") as f:  # rows counted in the extent but never written: zeros
        f[S.WRENCH_STREAM].resize(len(stream) + 7, axis=0)
    w = RunWriter.reopen(tail)
    try:
        assert w.n == 20 and w._stream_n == len(stream) == 1200
        np.testing.assert_array_equal(w.f[S.WRENCH_STREAM][()], stream)
    finally:
        w.close()
    middle = write_run(tmp_path / "middle.h5", close=False, samples=60, n=20)
    flip(middle, chunk_middle(middle, S.WRENCH_STREAM, 0))
    with pytest.raises(RunFileError, match=r"middle.h5: wrench_stream\[0:1024\]: checksum mismatch.*followed by rows"):
        RunWriter.reopen(middle)
    last = write_run(tmp_path / "last.h5", close=False, samples=60, n=20)
    flip(last, chunk_middle(last, S.WRENCH_STREAM, 1))  # the last chunk, cut short by the crash: dropped
    w = RunWriter.reopen(last)
    try:
        assert w.n == 20 and w._stream_n == 1024
    finally:
        w.close()
    closed = write_run(tmp_path / "closed.h5", samples=60, n=20)  # a closed run keeps everything or nothing
    flip(closed, chunk_middle(closed, S.WRENCH_STREAM, 1))
    with pytest.raises(RunFileError, match=r"closed.h5: wrench_stream\[1024:1200\]: checksum mismatch"):
        RunWriter.reopen(closed)
