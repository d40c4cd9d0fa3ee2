"""A process that opens the same closed, settled run file again reads its frames once; any change to
the file, a fresh file and a run still being written are checked in full every time."""

from __future__ import annotations

import os
import time

import pytest
from test_verified_reads import chunk_middle, flip, write_run

from acquisition import run_reader as R
from acquisition import schema as S
from acquisition.run_file import RunFileError, RunReader


@pytest.fixture
def counted(monkeypatch):
    """How many times the frames were read and checked; the file system's times seen as 10 s old."""
    calls = []
    real = R.check_frames

    def check(*args):
        calls.append(1)
        return real(*args)

    monkeypatch.setattr(R, "check_frames", check)
    monkeypatch.setattr(R, "_SOUND", {})
    monkeypatch.setattr(R, "now_ns", lambda: time.time_ns() + 10 * 10**9)
    return calls


def test_a_settled_closed_run_is_checked_once_and_again_after_any_change(tmp_path, counted):
    path = write_run(tmp_path / "run.h5")
    for _ in range(3):
        with RunReader.open(path) as run:
            assert run.n == 12
    assert len(counted) == 1
    st = os.stat(path)
    flip(path, chunk_middle(path, S.FRAMES, 4))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))  # its mtime put back: its ctime still moved
    with pytest.raises(RunFileError, match=rf"^{path}: frames\[4\]: checksum mismatch"):
        RunReader.open(path)
    assert len(counted) == 2


def test_a_file_changed_within_the_settling_time_is_checked_every_time(tmp_path, counted, monkeypatch):
    path = write_run(tmp_path / "run.h5")
    monkeypatch.setattr(R, "now_ns", time.time_ns)  # the file was written just now
    for _ in range(2):
        RunReader.open(path).close()
    assert len(counted) == 2


def test_a_run_still_being_written_is_checked_every_time(tmp_path, counted):
    path = write_run(tmp_path / "run.h5", close=False)
    for _ in range(2):
        with RunReader.open(path) as run:
            assert run.status == "running"
    assert len(counted) == 2


def test_the_verdict_belongs_to_the_file_opened_not_to_what_the_path_names_later(tmp_path, counted, monkeypatch):
    """The memory keys on the open file's own descriptor: a damaged file opened while the path still
    names a file found sound (renamed over it in between) is read through and refused."""
    path = write_run(tmp_path / "run.h5")
    RunReader.open(path).close()  # found sound, remembered
    damaged = write_run(tmp_path / "other.h5")
    flip(damaged, chunk_middle(damaged, S.FRAMES, 4))
    real_open = R.open_swmr_read
    monkeypatch.setattr(R, "open_swmr_read", lambda _path: real_open(damaged))  # the race, made certain
    with pytest.raises(RunFileError, match=r"frames\[4\]: checksum mismatch"):
        RunReader.open(path)
    assert len(counted) == 2
