"""Each frame in its place, and a writer that notices its file changing (issue 36; docs/run-file.md,
"Frame identity" and "A writer that notices"): swapped or foreign frame chunks with valid checksums,
rows moved with them, stream rows out of place; a file cut or replaced under its writer; a file
changed before the writer calls it complete."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from test_acquisition import QUICK
from test_verified_reads import write_run

from acquisition import schema as S
from acquisition.frame_identity import key_of
from acquisition.run_reader import RunReader
from acquisition.writer_lock import RunFileError
from dataset.runs import validate


def _swap_chunks(path: Path, a: int, b: int) -> None:
    with h5py.File(path, "r+") as f:
        d = f[S.FRAMES]
        z = (0,) * (d.ndim - 1)
        (ma, ra), (mb, rb) = d.id.read_direct_chunk((a, *z)), d.id.read_direct_chunk((b, *z))
        d.id.write_direct_chunk((a, *z), rb, mb)
        d.id.write_direct_chunk((b, *z), ra, ma)


def test_every_run_has_its_own_identity_and_a_digest_per_frame_and_stream_row(tmp_path):
    a, b = write_run(tmp_path / "a.h5"), write_run(tmp_path / "b.h5")
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        assert key_of(fa) != key_of(fb) and len(key_of(fa)) == 16
        assert fa[S.FRAME_DIGEST].shape == (12, 16) and fa[S.STREAM_DIGEST].shape == fa[S.WRENCH_STREAM].shape[:1]
        assert len({bytes(d) for d in fa[S.FRAME_DIGEST][()]}) == 12  # no two alike
    with RunReader.open(a) as run:
        assert run.n == 12 and run.frame(3).shape == (32, 32, 3)


def test_swapped_frames_with_valid_checksums_are_named_by_every_reader(tmp_path):
    path = write_run(tmp_path / "run.h5")
    _swap_chunks(path, 4, 5)
    with pytest.raises(RunFileError, match=r"frames\[4\]: not the frame written at this index .* and 1 more"):
        RunReader.open(path)
    assert any(line.startswith("frames[4]: not the frame written") for line in validate(path))


def test_a_chunk_from_another_run_is_not_taken_for_this_runs(tmp_path):
    """Two runs with the same frames (a frame copied over from one to the other is indistinguishable by
    its content and checksum): the digest is keyed by the run's identity."""
    a, b = write_run(tmp_path / "a.h5", seed=3), write_run(tmp_path / "b.h5", seed=3)
    with h5py.File(a, "r") as fa, h5py.File(b, "r+") as fb:
        z = (0, 0, 0)
        assert fa[S.FRAMES].id.read_direct_chunk((2, *z)) == fb[S.FRAMES].id.read_direct_chunk((2, *z))
        del fb[S.FRAME_DIGEST]  # b's digests replaced by a's: a forger without b's identity
        fb.create_dataset(S.FRAME_DIGEST, data=fa[S.FRAME_DIGEST][()], maxshape=(None, 16), chunks=(64, 16))
    with pytest.raises(RunFileError, match=r"frames\[0\]: not the frame written at this index"):
        RunReader.open(b)


def test_rows_moved_without_their_frames_are_found(tmp_path):
    path = write_run(tmp_path / "run.h5")
    with h5py.File(path, "r+") as f:
        wrench = f[S.WRENCH][()]
        f[S.WRENCH][3], f[S.WRENCH][4] = wrench[4], wrench[3]  # two rows swapped, values all plausible
    with pytest.raises(RunFileError, match=r"frames\[3\]: not the frame written at this index .* and 1 more"):
        RunReader.open(path)


def test_stream_rows_out_of_place_are_found(tmp_path):
    path = write_run(tmp_path / "run.h5")
    with h5py.File(path, "r+") as f:
        stream = f[S.WRENCH_STREAM][()]
        stream[[5, 6], 1:] = stream[[6, 5], 1:]  # two samples' wrenches swapped, their times kept
        f[S.WRENCH_STREAM][...] = stream
    with pytest.raises(RunFileError, match=r"wrench_stream\[5\]: not the row written at this index"):
        RunReader.open(path)


# -- a writer that notices -----------------------------------------------------------------------
def test_a_file_cut_under_its_writer_stops_the_writer(tmp_path):
    path = write_run(tmp_path / "run.h5", close=False)
    from acquisition.run_writer import RunWriter

    w = RunWriter.reopen(path)
    try:
        with open(path, "r+b") as other:  # another process cuts it
            other.truncate(int(path.stat().st_size * 0.6))
        frame = np.full((32, 32, 3), 99, np.uint8)
        row = S.blank_row() | {S.T_FRAME: 100.0, S.T_CAPTURE: 50.0, S.CAPTURE_INDEX: 12, S.LEVEL: 1}
        with pytest.raises(RunFileError, match=r"the file changed while it was written: it was cut from \d+ to \d+"):
            w.append(frame, **row)
        with pytest.raises(RunFileError, match="changed while it was written"):
            w.append(frame, **row)  # nothing more goes in
    finally:
        w.close()


def test_a_file_replaced_under_its_writer_is_not_called_complete(tmp_path):
    path = write_run(tmp_path / "run.h5", close=False)
    from acquisition.run_writer import RunWriter

    w = RunWriter.reopen(path)
    try:
        _swap_chunks(path, 2, 3)  # changed from outside, checksums valid, size kept
        with pytest.raises(RunFileError, match=r"changed while it was written: read back, frames\[2\]"):
            w.set_status("complete", "")
    finally:
        w.close()
    with h5py.File(path, "r") as f:
        assert f[S.STATUS][()] == b"aborted"


@pytest.mark.timeout(300)
def test_run_protocol_says_when_its_file_was_cut_and_exits_non_zero(tmp_path):
    """The issue's case: a run file cut by another process while `rig run-protocol` writes ended
    `complete: 153/153 frames`, rc 0."""
    proto = tmp_path / "slow.toml"
    proto.write_text(QUICK.replace("speed_mm_s = 0.1", "speed_mm_s = 0.02"))
    out = tmp_path / "run.h5"
    rig = str(Path(sys.executable).parent / "rig")
    proc = subprocess.Popen(
        [rig, "run-protocol", str(proto), "--sim", "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    try:
        progress = Path(str(out) + ".progress.json")
        for _ in range(6000):  # until the file holds a few frames (the writer's own sidecar says how many)
            if progress.exists() and re.search(r'"frame": ([3-9]|\d\d)', progress.read_text()):
                break
            try:
                proc.wait(timeout=0.05)
                break
            except subprocess.TimeoutExpired:
                pass
        with open(out, "r+b") as other:
            other.truncate(int(out.stat().st_size * 0.5))
        stdout, stderr = proc.communicate(timeout=240)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            proc.communicate()
    text = stdout.decode() + stderr.decode()
    assert proc.returncode not in (0, None), text
    assert "changed while it was written" in text and "complete:" not in text, text
    shutil.rmtree(tmp_path, ignore_errors=True) if os.environ.get("KEEP") is None else None
