"""Compressed, checksummed run files (issue 17): frames stored losslessly, one per chunk,
readable by plain h5py + hdf5plugin; old uncompressed files stay readable and
`dataset compact` rewrites them, verified before it replaces anything."""

import hashlib
import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from acquisition import run_compact
from acquisition import schema as S
from acquisition.run_compact import compact, frames_compressed
from acquisition.run_file import RunFileError, RunHeader, RunLocked, RunWriter, open_for_reading
from acquisition.run_layout import filter_ids
from acquisition.writer_lock import WriterLock
from cli.dataset_app import app as dataset_app
from dataset.interchange import export_run
from dataset.runs import check_run

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[1]
PHASES = ("approach", "press", "shear", "return", "twist", "untwist", "retract")
SIZE = 64


def frame(i: int) -> np.ndarray:
    """A smooth, sensor-like image with one grey level of noise: compressible, like real frames."""
    y, x = np.mgrid[0:SIZE, 0:SIZE]
    base = 120 + 60 * np.sin((x + 3 * i) / 9.0)[..., None] * np.array([1.0, 0.6, 0.3]) + 0.5 * y[..., None]
    noise = np.random.default_rng(i).normal(0, 1, (SIZE, SIZE, 3))
    return np.clip(base + noise, 0, 255).astype(np.uint8)


def write_run(path, n=12, *, compress=True, codec=None):
    header = RunHeader("test", "# x", "", "sphere10mm", "", "rgb", 0.5, 1.0, n, (0, 0, 0, 0), PHASES)
    w = RunWriter.create(path, header, (SIZE, SIZE, 3), frame(99), frame(98), compress=compress, codec=codec)
    for i in range(n):
        w.append(
            frame(i),
            **S.blank_row()
            | {S.WRENCH: np.full(6, 0.1 * i), S.T_FRAME: float(i), S.T_CAPTURE: float(i), S.CAPTURE_INDEX: i},
        )
    w.set_status("complete", "")
    w.close()
    return path


def digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("codec", [None, *S.FRAME_CODECS])
def test_compressed_frames_round_trip_frame_by_frame(tmp_path, codec):
    path = write_run(tmp_path / "run.h5", codec=codec)
    with open_for_reading(path) as f:
        d = f[S.FRAMES]
        assert frames_compressed(f) and d.fletcher32 and d.chunks == (1, SIZE, SIZE, 3)
        # the codec, then the checksum over the bytes on disk; by default the image codec
        assert filter_ids(d) == [S.FRAME_CODECS[codec or S.IMAGE_CODEC]["compression"], h5py.h5z.FILTER_FLETCHER32]
        for i in range(d.shape[0]):
            np.testing.assert_array_equal(d[i], frame(i), err_msg=f"frame {i}")
    assert check_run(path).findings == []
    # plain h5py with the plugin reads it, without any of this project's code
    code = textwrap.dedent("""
        import sys, h5py, hdf5plugin
        with h5py.File(sys.argv[1], "r") as f:
            print(int(f["frames"][:].astype("int64").sum()))
    """)
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, check=True)
    assert int(out.stdout) == int(sum(frame(i).astype(np.int64).sum() for i in range(12)))
    export_run(path, tmp_path / "png")
    np.testing.assert_array_equal(cv2.imread(str(tmp_path / "png" / "frames" / "000005.png")), frame(5))


def test_an_old_uncompressed_file_reads_validates_and_compacts(tmp_path):
    path = write_run(tmp_path / "old.h5", compress=False)
    with open_for_reading(path) as f:
        assert not frames_compressed(f)
    assert check_run(path).findings == []
    with open_for_reading(path) as f:
        raw = f[S.FRAMES].id.get_storage_size()
    result = compact(path)
    assert result.done and result.frames == 12
    with open_for_reading(path) as f:
        assert frames_compressed(f) and f[S.FRAMES].fletcher32
        assert f[S.FRAMES].id.get_storage_size() < 0.8 * raw
        for i in range(12):
            np.testing.assert_array_equal(f[S.FRAMES][i], frame(i))
        np.testing.assert_array_equal(f[S.WRENCH][:, 0], 0.1 * np.arange(12))
        assert f[S.STATUS][()] == b"complete" and list(f.attrs[S.ATTR_PHASES]) == list(PHASES)
    assert check_run(path).findings == []
    assert not compact(path).done  # already compressed: untouched
    assert not list(tmp_path.glob("old.h5.*"))  # no temp file, no lock left


def test_compact_refuses_a_file_being_written(tmp_path):
    path = write_run(tmp_path / "run.h5", compress=False)
    before = digest(path)
    lock = WriterLock.acquire(path)  # what a live writer (or --resume) holds
    try:
        with pytest.raises(RunLocked, match="being written"):
            compact(path)
        result = runner.invoke(dataset_app, ["compact", str(path)])
        assert result.exit_code == 1 and "being written by pid" in result.output
    finally:
        lock.release()
    assert digest(path) == before


@pytest.mark.parametrize("failure", ["copy", "verify"])
def test_compact_leaves_the_original_on_any_failure(tmp_path, monkeypatch, failure):
    path = write_run(tmp_path / "run.h5", compress=False)
    before = digest(path)
    if failure == "copy":

        def broken_copy(src, dst, frame=None):
            raise OSError(28, "No space left on device")

        monkeypatch.setattr(run_compact, "_copy", broken_copy)
        words = "compacting failed, the original is unchanged"
    else:
        monkeypatch.setattr(run_compact, "_verify", lambda src, copy: "frames[3] differs")
        words = r"does not match \(frames\[3\] differs\); the original is unchanged"
    with pytest.raises(RunFileError, match=words):
        compact(path)
    assert digest(path) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]


def test_verify_finds_a_changed_frame(tmp_path):
    a = write_run(tmp_path / "a.h5", compress=False)
    b = write_run(tmp_path / "b.h5")
    with h5py.File(a, "r") as fa, h5py.File(b, "r+") as fb:
        fb.attrs[S.ATTR_CREATED] = fa.attrs[S.ATTR_CREATED]  # written a second apart, maybe
        fb.attrs[S.ATTR_RUN_ID] = fa.attrs[S.ATTR_RUN_ID]  # each run has its own identity...
        fb.attrs[S.ATTR_ATTRS_SHA256] = fa.attrs[S.ATTR_ATTRS_SHA256]  # ...and so checksummed apart
        del fb[S.FRAME_DIGEST]
        run_compact._redigest(fb)  # b's frames signed as a's identity would sign them
        assert run_compact._verify(fa, fb) == ""
    with h5py.File(b, "r+") as fb:
        fb[S.FRAMES][7] = frame(8)
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        assert run_compact._verify(fa, fb) == "frames[7] differs"


def test_dataset_compact_command(tmp_path):
    path = write_run(tmp_path / "run.h5", compress=False)
    result = runner.invoke(dataset_app, ["compact", str(path)])
    assert result.exit_code == 0 and "12 frames compacted" in result.output, result.output
    result = runner.invoke(dataset_app, ["compact", str(path)])
    assert result.exit_code == 0 and "already compressed; unchanged" in result.output


def test_frame_codec_choice():
    """HTJ2K takes 1 or 3 channels; other frames get the fast codec; a wrong name is refused."""
    assert S.frame_codec((480, 640, 3)) == S.frame_codec((32, 32, 1)) == S.IMAGE_CODEC
    assert S.frame_codec((32, 32, 4)) == S.frame_codec((32, 32, 2)) == S.FAST_CODEC
    assert S.frame_codec((32, 32, 3), S.FAST_CODEC) == S.FAST_CODEC
    with pytest.raises(ValueError, match="frame codec must be one of"):
        S.frame_codec((32, 32, 3), "gzip")


def test_four_channel_frames_are_stored_with_the_fast_codec(tmp_path):
    header = RunHeader("test", "# x", "", "sphere10mm", "", "rgb", 0.5, 1.0, 2, (0, 0, 0, 0), PHASES)
    image = np.dstack([frame(1), frame(2)[..., :1]])
    w = RunWriter.create(tmp_path / "rgba.h5", header, image.shape, frame(99), image)
    w.append(image, **S.blank_row() | {S.CAPTURE_INDEX: 0})
    w.close()
    with open_for_reading(tmp_path / "rgba.h5") as f:
        assert filter_ids(f[S.FRAMES])[0] == S.FRAME_CODECS[S.FAST_CODEC]["compression"]
        np.testing.assert_array_equal(f[S.FRAMES][0], image)


@pytest.mark.parametrize("codec", list(S.FRAME_CODECS))
def test_merge_keeps_the_runs_codec_and_frames(tmp_path, codec):
    """A merge of simulated runs (the fast codec) stays in it; of camera runs, in HTJ2K."""
    from acquisition.run_storage import frames_codec
    from dataset.merge import merge_runs

    a = write_run(tmp_path / "a.h5", n=3, codec=codec)
    b = write_run(tmp_path / "b.h5", n=2, codec=codec)
    assert merge_runs([a, b], tmp_path / "merged.h5") == 5
    with open_for_reading(tmp_path / "merged.h5") as f:
        assert frames_codec(f) == codec
        for i, j in enumerate([0, 1, 2, 0, 1]):
            np.testing.assert_array_equal(f[S.FRAMES][i], frame(j))


def test_a_missing_codec_plugin_is_one_line_and_keeps_every_frame(tmp_path):
    """Without the HTJ2K filter (an old or stripped hdf5plugin) reading or resuming a run must
    say so in one line: the frames must not pass for frames that never reached the disk and
    be trimmed away on resume."""
    header = RunHeader("test", "# x", "", "sphere10mm", "", "rgb", 0.5, 1.0, 9, (0, 0, 0, 0), PHASES)
    path = tmp_path / "run.h5"
    w = RunWriter.create(path, header, (SIZE, SIZE, 3), frame(99), frame(98), codec=S.IMAGE_CODEC)
    for i in range(3):
        w.append(frame(i), **S.blank_row() | {S.CAPTURE_INDEX: i})
    w.close()  # left "running": a resume would look for unfinished frames
    code = textwrap.dedent(f"""
        import sys, h5py
        from acquisition.run_file import RunFileError, RunWriter, open_for_reading
        h5py.h5z.unregister_filter({S.CODEC_FILTER_IDS[S.IMAGE_CODEC]})
        for what in (open_for_reading, RunWriter.reopen):
            try:
                what(sys.argv[1])
            except RunFileError as exc:
                print(exc)
            else:
                print("opened")
    """)
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, cwd=ROOT)
    lines = out.stdout.splitlines()
    assert out.returncode == 0 and len(lines) == 2, out.stdout + out.stderr
    for line in lines:
        assert line.startswith(f"{path}: ") and "frames: stored with htj2k (HDF5 filter 32033)" in line
        assert "cannot decode: install hdf5plugin 7.1 or later" in line
    with open_for_reading(path) as f:  # every frame still there
        assert f[S.FRAMES].shape[0] == 3
        np.testing.assert_array_equal(f[S.FRAMES][2], frame(2))


def test_frames_of_another_dtype_are_refused_before_anything_is_written(tmp_path):
    path = write_run(tmp_path / "run.h5", n=2)
    w = RunWriter.reopen(path)
    with pytest.raises(RunFileError, match=r"frame dtype float64, the run's frames are uint8"):
        w.append(frame(5).astype(float), **S.blank_row() | {S.CAPTURE_INDEX: 2})
    w.append(frame(5), **S.blank_row() | {S.CAPTURE_INDEX: 2})
    w.close()
    with open_for_reading(path) as f:
        assert f[S.FRAMES].shape[0] == 3
        np.testing.assert_array_equal(f[S.FRAMES][2], frame(5))
