"""The run file cannot lie: one writer, atomic creation, checksums, disk full, broken files.

Each test here failed on the code before these guarantees (the reason is in its docstring).
"""

import errno
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from test_acquisition import QUICK, ctrl_c, interrupt_at, run
from test_dataset import make_run
from typer.testing import CliRunner

from acquisition import attr_checksum
from acquisition import schema as S
from acquisition.executor import Acquisition
from acquisition.run_file import RunFileError, RunLocked, RunWriter, open_for_reading
from cli.dataset_app import app as dataset_app
from cli.rig_app import app as rig_app
from cli.simulated import monitor_interval_s, simulated_rig_for
from dataset.runs import check_run, validate
from protocols.plan import Plan

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


@pytest.fixture
def quick(tmp_path):
    from protocols.spec import load_protocol

    path = tmp_path / "quick.toml"
    path.write_text(QUICK)
    return load_protocol(path)


def python(script: str, *args, **kwargs) -> subprocess.Popen:
    """A Python subprocess running ``script`` in the repository, with ``args`` as sys.argv[1:]."""
    env = dict(os.environ, PYTHONPATH=f"{ROOT}{os.pathsep}{ROOT / 'tests'}")
    return subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(script), *map(str, args)], cwd=ROOT, env=env, text=True, **kwargs
    )


def row(i: int) -> dict:
    return {
        S.WRENCH: np.full(6, 0.1 * i),
        S.POSE_COMMANDED: np.zeros(4),
        S.POSE_MEASURED: np.zeros(4),
        S.T_FRAME: float(i),
        S.T_CAPTURE: float(i),
        S.WRENCH_SKEW: 0.001,
        S.CAPTURE_INDEX: i,
        S.STEP_INDEX: 0,
        S.PHASE_INDEX: 1,
        S.LEVEL: 1,
        S.RETAKE: 0,
    }


def frame(i: int, size: int = 32) -> np.ndarray:
    return np.random.default_rng(i).integers(20, 230, (size, size, 3), dtype=np.uint8)


# A writer in another process: creates RUN (argv[1]), appends two frames, says so, then
# waits for a line on stdin before appending two more and closing.
HOLDER = """
    import sys
    import numpy as np
    from acquisition.run_file import RunHeader, RunWriter
    from protocols.plan import PHASES
    from test_run_file_integrity import frame, row

    header = RunHeader("test", "# x", "", "sphere10mm", "", "rgb", 0.5, 1.0, 4, (0, 0, 0, 0), PHASES)
    w = RunWriter.create(sys.argv[1], header, (32, 32, 3), frame(99), frame(98))
    for i in range(2):
        w.append(frame(i), **row(i))
    print("writing", flush=True)
    sys.stdin.readline()
    for i in range(2, 4):
        w.append(frame(i), **row(i))
    w.set_status("complete", "")
    w.close()
    print("closed", flush=True)
"""


def test_a_live_writer_keeps_resume_and_a_second_writer_out(tmp_path, quick):
    """Before: --resume copied the file and replaced it under its live writer; both 'completed'."""
    out = tmp_path / "run.h5"
    holder = python(HOLDER, out, stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    try:
        assert holder.stdout.readline().strip() == "writing"
        with pytest.raises(RunLocked, match=rf"being written by pid {holder.pid} on host .*delete .*run\.h5\.lock"):
            RunWriter.reopen(out)
        with pytest.raises(RunLocked, match=rf"pid {holder.pid}"):
            RunWriter.claim(out)
        result = runner.invoke(rig_app, ["run-protocol", str(quick.path), "--sim", "--resume", str(out)])
        assert result.exit_code == 1 and f"pid {holder.pid}" in result.output, result.output
        errors = [line for line in result.output.splitlines() if line.startswith("error:")]
        assert "Traceback" not in result.output and len(errors) == 1, result.output  # the progress bar aside
        holder.stdin.write("go on\n")
        holder.stdin.flush()
        assert holder.stdout.readline().strip() == "closed"
        assert holder.wait(timeout=30) == 0
    finally:
        if holder.poll() is None:
            holder.kill()
    with open_for_reading(out) as f:  # the holder's run, untouched by the refused ones
        assert f[S.FRAMES].shape[0] == 4 and f[S.STATUS][()] == b"complete"
        np.testing.assert_array_equal(f[S.CAPTURE_INDEX][:], np.arange(4))
    assert not (tmp_path / "run.h5.lock").exists()
    RunWriter.reopen(out).close()  # the writer is gone: resuming is allowed again


def test_kill_9_of_a_writer_leaves_no_stale_lock(tmp_path):
    """The kernel drops an flock with its process: a crashed writer never blocks --resume."""
    out = tmp_path / "run.h5"
    holder = python(HOLDER, out, stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    try:
        assert holder.stdout.readline().strip() == "writing"
        os.kill(holder.pid, signal.SIGKILL)
        holder.wait(timeout=30)
    finally:
        if holder.poll() is None:
            holder.kill()
    w = RunWriter.reopen(out)
    try:
        assert w.n == 2
        w.append(frame(2), **row(2))
    finally:
        w.close()
    assert validate(out) == [f"{S.STATUS}: 'running', not complete (no reason)"]


def test_time_stays_monotonic_across_two_resumes(quick, tmp_path):
    """Before: t_frame_s restarted with every process's clock, so validate failed every resumed run."""
    out = tmp_path / "run.h5"
    first, _ = run(quick, out, progress=interrupt_at(6, ctrl_c))
    assert first.status == "interrupted" and first.frames == 6
    second, _ = run(quick, out, resume=True, progress=interrupt_at(14, ctrl_c))
    assert second.status == "interrupted" and second.frames == 14
    third, _ = run(quick, out, resume=True)
    assert third.status == "complete"
    with open_for_reading(out) as f:
        t = f[S.T_FRAME][:]
        np.testing.assert_array_equal(f[S.CAPTURE_INDEX][:], np.arange(Plan.of(quick).frame_count))
    steps = np.diff(t)
    assert np.all(steps > 0), steps
    assert steps[5] >= 1.0 and steps[13] >= 1.0  # at least a capture period across each resume
    np.testing.assert_allclose(np.delete(steps, [5, 13]), 1.0, atol=0.02)  # 1 Hz within each part
    assert validate(out) == []


# Stops itself with SIGKILL half-way through writing the header of RUN (argv[1]).
KILLED_IN_CREATE = """
    import os, signal, sys
    import h5py
    from acquisition import schema as S
    from acquisition.run_file import RunHeader, RunWriter
    from protocols.plan import PHASES
    from test_run_file_integrity import frame

    create = h5py.Group.create_dataset

    def dying(self, name, *args, **kwargs):
        if name == S.REFERENCE_FRAME:
            self.file.flush()  # what is written so far is on disk, as after a real crash
            os.kill(os.getpid(), signal.SIGKILL)
        return create(self, name, *args, **kwargs)

    h5py.Group.create_dataset = dying
    header = RunHeader("test", "# x", "", "sphere10mm", "", "rgb", 0.5, 1.0, 4, (0, 0, 0, 0), PHASES)
    RunWriter.create(sys.argv[1], header, (32, 32, 3), frame(99), frame(98))
"""


def test_kill_9_during_creation_then_resume_and_a_new_run(quick, tmp_path):
    """Before: a stub was left at --out that info, validate and resume rejected and a new run refused."""
    out = tmp_path / "run.h5"
    proc = python(KILLED_IN_CREATE, out)
    assert proc.wait(timeout=60) == -signal.SIGKILL
    assert not out.exists()
    stray = list(tmp_path.glob("run.h5.creating-*"))
    assert len(stray) == 1 and stray[0].stat().st_size > 0  # a crash leaves only the temp file
    with pytest.raises(
        RunFileError,
        match=r"no such run file to resume \(a crash interrupted its creation; removed "
        r"run\.h5\.creating-\d+\); start a new run",
    ):
        RunWriter.reopen(out)
    assert not list(tmp_path.glob("run.h5.creating-*"))
    proc = python(KILLED_IN_CREATE, out)  # again, and this time a new run at the same --out
    assert proc.wait(timeout=60) == -signal.SIGKILL
    result, _ = run(quick, out)
    assert result.status == "complete" and validate(out) == []
    assert not list(tmp_path.glob("run.h5.*"))  # no temp file, no lock sidecar left


@pytest.mark.parametrize("kept", [0.01, 0.999])
def test_truncated_file_fails_fast_naming_it(tmp_path, kept):
    """Before: 1 % kept `dataset info` in HDF5 retries for over 20 minutes; 99.9 % passed validate."""
    whole = make_run(tmp_path / "whole.h5", n=40, size=64)
    cut = tmp_path / "cut.h5"
    data = whole.read_bytes()
    cut.write_bytes(data[: int(len(data) * kept)])
    started = time.monotonic()
    info = subprocess.run(
        [str(Path(sys.executable).parent / "dataset"), "info", str(cut)], capture_output=True, text=True, timeout=60
    )
    elapsed = time.monotonic() - started
    assert info.returncode == 1 and elapsed < 15, (elapsed, info.stderr)
    assert f"{cut}: truncated: {int(len(data) * kept):,} of its {len(data):,} bytes" in info.stderr, info.stderr
    assert "Traceback" not in info.stderr + info.stdout and len(info.stderr.strip().splitlines()) == 1
    assert [line.split(":")[0] for line in validate(cut)] == ["file"] and "truncated" in validate(cut)[0]
    with pytest.raises(RunFileError, match=rf"{cut}: truncated.*cannot resume"):
        RunWriter.reopen(cut)


def test_zeroed_metadata_fails_fast(tmp_path):
    """The end of the file zeroed, not cut: its size is right, so only bounded SWMR retries
    keep HDF5 from doubling its wait for a "half-written" header (before: over 20 minutes)."""
    path = make_run(tmp_path / "run.h5", n=40, size=64)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 100] + bytes(len(data) - len(data) // 100))
    started = time.monotonic()
    findings = validate(path)
    assert time.monotonic() - started < 10, findings
    named = {fl.path for fl in S.FIELDS} | {f"attribute {name}" for name, _ in (*S.ATTRS, *S.OPTIONAL_ATTRS)} | {"file"}
    assert findings and all(line.split(":")[0] in named for line in findings), findings
    info = runner.invoke(dataset_app, ["info", str(path)])
    assert info.exit_code == 1 and str(path) in info.output and "Traceback" not in info.output, info.output


def test_validate_catches_a_corrupted_last_frame_and_row(tmp_path):
    """Before: no checksums, and only 64 sampled frames were looked at; flipped bytes passed."""
    path = make_run(tmp_path / "run.h5", n=40, size=64)
    assert validate(path) == []
    with h5py.File(path, "r") as f:
        last = f[S.FRAMES].id.get_chunk_info(f[S.FRAMES].id.get_num_chunks() - 1)
        wrench = f[S.WRENCH].id.get_chunk_info(0)
        assert last.chunk_offset[0] == 39
    data = bytearray(path.read_bytes())
    for at in (last.byte_offset + last.size // 2, wrench.byte_offset + 40):
        data[at : at + 4] = bytes(b ^ 0x5A for b in data[at : at + 4])
    path.write_bytes(bytes(data))
    findings = validate(path)
    assert "frames[39]: checksum mismatch or missing bytes" in findings, findings
    assert any(line.startswith("wrench: unreadable") for line in findings), findings
    assert "frames[39]: checksum mismatch or missing bytes" in validate(path, sample_frames=5)
    result = runner.invoke(dataset_app, ["validate", str(path)])
    assert result.exit_code == 1 and f"{path}: frames[39]: checksum mismatch" in result.output
    info = runner.invoke(dataset_app, ["info", str(path)])
    assert info.exit_code == 1 and f"{path}: wrench: unreadable" in info.output and "Traceback" not in info.output


def test_validate_reads_every_frame_unless_asked_to_sample(tmp_path):
    """Before: a black frame between the 64 sampled ones passed."""
    from acquisition.frame_identity import frame_digest, key_of, row_bytes, stored_chunk

    path = make_run(tmp_path / "run.h5", n=200, size=16)
    with h5py.File(path, "r+") as f:
        f[S.FRAMES][101] = 0
        f[S.FRAMES][150] = 77  # constant: a stuck camera, not black
        # as a camera would have given them: their identity digests are of these frames
        rows = {fl.path: f[fl.path][()] for fl in S.PER_FRAME_FIELDS}
        for i in (101, 150):
            row = row_bytes({k: v[i] for k, v in rows.items()})
            f[S.FRAME_DIGEST][i] = frame_digest(key_of(f), i, stored_chunk(f[S.FRAMES], i), row)
    assert validate(path) == ["frames[101]: all black", "frames[150]: constant"]
    assert validate(path, sample_frames=4) == []
    notes = check_run(path, sample_frames=4).notes
    assert notes == ["frames: 4 of 200 checked (--sample); run without it to check every frame"]


def _drop(name):
    def change(f):
        del f[name]

    return change


def _replace(name, data):
    def change(f):
        del f[name]
        f.create_dataset(name, data=data)

    return change


def _drop_attr(name):
    def change(f):
        del f.attrs[name]

    return change


BROKEN = {
    "no reference_frame": (_drop(S.REFERENCE_FRAME), S.REFERENCE_FRAME, "missing"),
    "no t_capture_s": (_drop(S.T_CAPTURE), S.T_CAPTURE, "missing"),
    "no phase_index": (_drop(S.PHASE_INDEX), S.PHASE_INDEX, "missing"),
    "no level": (_drop(S.LEVEL), S.LEVEL, "missing"),
    "no stop reason": (_drop(S.STATUS_REASON), S.STATUS_REASON, "missing"),
    "integer status": (_replace(S.STATUS, 3), S.STATUS, "dtype int64, expected |S16"),
    "text wrenches": (_replace(S.WRENCH, np.array([[b"1.0"] * 6] * 20)), S.WRENCH, "dtype |S3, expected float64"),
    "2-D t_frame_s": (_replace(S.T_FRAME, np.zeros((20, 2))), S.T_FRAME, "shape (20, 2), expected (N)"),
}


@pytest.mark.parametrize("case", list(BROKEN))
def test_each_missing_or_malformed_dataset_is_one_line_naming_it(tmp_path, case):
    """Before: validate passed the missing ones; info and --resume gave tracebacks for the malformed."""
    change, name, words = BROKEN[case]
    path = make_run(tmp_path / "run.h5", n=20, size=16)
    with h5py.File(path, "r+") as f:
        change(f)
    assert f"{name}: {words}" in validate(path)
    result = runner.invoke(dataset_app, ["validate", str(path)])
    assert result.exit_code == 1 and f"  {path}: {name}: {words}" in result.output.splitlines()
    info = runner.invoke(dataset_app, ["info", str(path)])
    assert info.exit_code == 1 and str(path) in info.output and name in info.output, info.output
    assert "Traceback" not in info.output and len(info.output.strip().splitlines()) == 1, info.output
    with pytest.raises(RunFileError, match=rf"{path}: cannot resume: .*{name}: "):
        RunWriter.reopen(path)


def test_a_missing_attribute_is_a_finding(tmp_path):
    path = make_run(tmp_path / "run.h5", n=5, size=16)
    with h5py.File(path, "r+") as f:  # as a writer that wrote them so would have left them (checksum and all)
        del f.attrs[S.ATTR_CAPTURE_HZ]
        f.attrs[S.ATTR_CONTACT_ORIGIN] = "here"
        attr_checksum.seal(f)
    assert validate(path) == [
        f"attribute {S.ATTR_CAPTURE_HZ}: missing",
        f"attribute {S.ATTR_CONTACT_ORIGIN}: is 'here', expected 4 numbers",
    ]


def test_old_files_without_checksums_stay_readable(tmp_path):
    new = make_run(tmp_path / "new.h5", n=10, size=16)
    old = tmp_path / "old.h5"
    with h5py.File(new, "r") as src, h5py.File(old, "w") as dst:  # the layout before checksums
        for key, value in src.attrs.items():
            dst.attrs[key] = value

        def copy(name, obj):
            if isinstance(obj, h5py.Dataset):
                dst.create_dataset(name, data=obj[()], maxshape=obj.maxshape, chunks=obj.chunks)
                dst[name].attrs.update(obj.attrs)

        src.visititems(copy)
        assert not dst[S.FRAMES].fletcher32
    check = check_run(old)
    assert check.findings == [] and check.notes[0].startswith("no checksums (old file)")
    result = runner.invoke(dataset_app, ["validate", str(old)])
    assert result.exit_code == 0 and "note: no checksums (old file)" in result.output


def _raise_enospc_on_frames(monkeypatch) -> list:
    """Make the writer's frame writes fail as on a full disk, after the frames dataset has
    grown by the frame (as HDF5 fails: the extent is set, the chunk never lands); returns
    the indices that failed."""
    failed = []

    def full(self, frames, i, image):
        failed.append(i)
        frames.id.set_extent((i + 1, *self._frame_shape))
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(RunWriter, "_write_frame", full)
    return failed


def test_disk_full_commits_nothing_partial_and_resume_works(tmp_path, monkeypatch):
    """Before: the OSError escaped untyped, and close() kept a frame whose chunk never reached the disk."""
    path = make_run(tmp_path / "run.h5", n=5, size=32, status="running")
    w = RunWriter.reopen(path)
    failed = _raise_enospc_on_frames(monkeypatch)
    with pytest.raises(
        RunFileError,
        match=rf"{path}: disk full: frame 5 could not be written "
        r"\(No space left on device\); frames 0-4 are kept",
    ):
        w.append(frame(5), **row(5))
    assert failed == [5]
    with pytest.raises(RunFileError, match="disk full"):  # nothing more goes in after a failure
        w.append(frame(6), **row(6))
    w.set_status("aborted", "stopped by an error")
    w.close()
    monkeypatch.undo()
    with open_for_reading(path) as f:
        assert f[S.FRAMES].shape[0] == 5 and f[S.WRENCH].shape[0] == 5
        assert f[S.STATUS][()] == b"aborted" and f[S.STATUS_REASON][()].startswith(b"disk full: frame 5")
    assert validate(path) == [
        f"{S.STATUS}: 'aborted', not complete (disk full: frame 5 could not be written "
        "(No space left on device); frames 0-4 are kept; stopped by an error)"
    ]
    w = RunWriter.reopen(path)
    for i in range(5, 8):
        w.append(frame(i), **row(i))
    w.set_status("complete")
    w.close()
    assert validate(path) == []


# Writes 64x64 frames into RUN (argv[1]), under a file-size limit of argv[2] bytes unless 0,
# until the disk or the limit is full. Prints what it saw.
FILLS_THE_DISK = """
    import resource, signal, sys
    import numpy as np
    from acquisition.run_file import RunFileError, RunHeader, RunWriter
    from protocols.plan import PHASES
    from test_run_file_integrity import frame, row

    if int(sys.argv[2]):
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG instead
        resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[2]), int(sys.argv[2])))
    if sys.argv[3] == "into-hdf5":  # no free-space check: HDF5's own write fails, and is rolled back
        RunWriter._check_space = lambda self, i, frame_bytes: None
    header = RunHeader("test", "# x", "", "sphere10mm", "", "rgb", 0.5, 1.0, 400, (0, 0, 0, 0), PHASES)
    w = RunWriter.create(sys.argv[1], header, (64, 64, 3), frame(99, 64), frame(98, 64))
    try:
        for i in range(400):
            w.append(frame(i, 64), **row(i))
    except RunFileError as exc:
        print(exc, flush=True)
    w.set_status("aborted", "stopped by an error")
    w.close()
    print("frames", w.n, flush=True)
"""


def _check_filled(path: Path, out: str, words: str) -> None:
    assert words in out, out
    n = int(out.split("frames ")[-1])
    assert 10 < n < 400
    with open_for_reading(path) as f:
        assert f[S.FRAMES].shape[0] == n and f[S.STATUS][()] == b"aborted"
        assert words.encode() in f[S.STATUS_REASON][()]
        frames = f[S.FRAMES][:]  # every chunk's checksum holds
    assert all(img.max() > 8 for img in frames)  # no all-zero frame committed
    w = RunWriter.reopen(path)  # --resume works afterwards
    w.append(frame(n, 64), **row(n))
    w.close()


def test_a_file_size_limit_stops_the_run_without_a_crash(tmp_path):
    """Before: a traceback, then a segfault (rc 139) at exit, and an all-zero frame in the file."""
    path = tmp_path / "run.h5"
    proc = python(FILLS_THE_DISK, path, 3_000_000, "checked", stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, (proc.returncode, err[-2000:])
    assert "Traceback" not in err and "Segmentation" not in err, err[-2000:]
    _check_filled(path, out, "file too large")


def user_namespaces() -> bool:
    """Can this process mount a filesystem of its own (a user and mount namespace, `unshare`)?"""
    if not shutil.which("unshare"):
        return False
    probe = subprocess.run(["unshare", "--user", "--map-root-user", "--mount", "true"], capture_output=True)
    return probe.returncode == 0


@pytest.mark.parametrize("mode", ["checked", "into-hdf5"])
def test_a_really_full_disk(tmp_path, mode):
    """A 2 MB tmpfs in a user namespace, where the system allows one: real ENOSPC, stopped by
    the free-space check or (into-hdf5) failing inside HDF5's own write and rolled back."""
    if not user_namespaces():
        pytest.skip("no user namespaces here to mount a small tmpfs")
    disk = tmp_path / "disk"
    disk.mkdir()
    script = tmp_path / "fill.py"
    script.write_text(textwrap.dedent(FILLS_THE_DISK))
    proc = subprocess.run(
        [
            "unshare",
            "--user",
            "--map-root-user",
            "--mount",
            "sh",
            "-c",
            f"mount -t tmpfs -o size=2m tmpfs {disk} && cd {ROOT} && "
            f"PYTHONPATH={ROOT}:{ROOT / 'tests'} {sys.executable} {script} {disk}/run.h5 0 {mode} && "
            f"cp {disk}/run.h5 {tmp_path}/copy.h5",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr, proc.stderr[-2000:]
    _check_filled(tmp_path / "copy.h5", proc.stdout, "disk full")


def test_disk_full_mid_run_stops_retracts_and_resume_completes(quick, tmp_path, monkeypatch):
    """Before: the OSError skipped stop-and-retract and the file kept no reason."""
    out = tmp_path / "run.h5"
    failed = []

    def fill_disk_at_frame_6(sim):
        failed.extend(_raise_enospc_on_frames(monkeypatch))

    with simulated_rig_for(quick) as (rig, sim, header):
        acq = Acquisition(
            rig,
            Plan.of(quick),
            monitor_interval_s=monitor_interval_s(quick),
            progress=interrupt_at(6, fill_disk_at_frame_6)(sim),
        )
        with pytest.raises(RunFileError, match=rf"{out}: disk full: frame 6"):
            acq.run(out, header=header)
        z_after = rig.positions()["z"]
    monkeypatch.undo()
    assert z_after == pytest.approx(quick.approach_mm, abs=1e-3)  # stopped and lifted clear
    with open_for_reading(out) as f:
        assert f[S.FRAMES].shape[0] == 6 and f[S.STATUS][()] == b"aborted"
        assert f[S.STATUS_REASON][()].startswith(b"disk full: frame 6 could not be written")
        assert all(img.max() > 8 for img in f[S.FRAMES][:])
    result, _ = run(quick, out, resume=True)
    assert result.status == "complete" and validate(out) == []


def test_optional_attributes_are_checked_when_present(tmp_path):
    """A run may lack the optional attributes (older files); when one is there, its kind is checked."""
    import h5py

    from acquisition import schema as S
    from acquisition.run_layout import attr_problems

    path = tmp_path / "a.h5"
    with h5py.File(path, "w") as f:
        for name, kind in S.ATTRS:
            f.attrs[name] = {"str": "x", "float": 1.0, "int": 1, "float[4]": [0.0] * 4, "str[]": ["a"]}[kind]
        f.attrs[S.ATTR_SENSOR_KIND] = "rgb"  # text, and one of the sensor kinds
    with h5py.File(path, "r") as f:
        assert attr_problems(f) == {}
    with h5py.File(path, "a") as f:
        f.attrs[S.OPTIONAL_ATTRS[0][0]] = [1, 2, 3]  # a list of numbers where text belongs
    with h5py.File(path, "r") as f:
        assert attr_problems(f) == {S.OPTIONAL_ATTRS[0][0]: "is int64 array of shape (3,), expected text"}
