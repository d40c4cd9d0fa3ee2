"""Issue 25: every reader verifies what it reads; merge, import and profiles never guess.

The corruption corpus × every command is tests/test_corruption_corpus.py; here: the chunk checksum
against HDF5's own verdict, resume of a crashed run, merge of two good runs (valid, time increasing,
every field carried), the all-or-nothing strict import, read-only output folders, runs without a
sensor profile, and messages that used to name nothing.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
from test_run_file_integrity import user_namespaces
from typer.testing import CliRunner

from acquisition import schema as S
from acquisition.chunk_checksum import bad_chunks, checksum_ok
from acquisition.run_file import RunFileError, RunHeader, RunReader, RunWriter
from cli.dataset_app import app as dataset_app
from cli.model_app import app as train_app
from cli.model_app import evaluate_app, generate_app
from cli.rig_app import app as rig_app
from dataset.interchange import export_run
from dataset.runs import validate
from dataset.split import make_split
from objects.indenters import get_indenter
from protocols.plan import PHASES
from sensor_sim.profile import default_profile

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()
SIZE = 32


def write_run(
    path: Path,
    n: int = 12,
    *,
    seed: int = 0,
    profile: str | None = None,
    phases=PHASES,
    phase: str = "press",
    mm_per_px: float = 14 / SIZE,
    t0: float = 1.0,
    close: bool = True,
    object_file: str = "",
    codec: str | None = S.FAST_CODEC,
    varied: bool = False,
    protocol=None,
    written: int | None = None,
    samples: int = 3,
    size: int = SIZE,
) -> Path:
    """A run of ``n`` frames with a full-rate stream; ``profile`` the record it keeps (default: the
    shipped profile's; "": none); ``close=False`` leaves it as a crash would (status running);
    ``protocol``: recorded as its run (name, text, rate), for ``--resume`` with it; ``written``: the
    frames written of the ``n`` planned (default all); ``samples``: stream rows per frame; ``size``: the
    frames' side in pixels."""
    record = default_profile().record() if profile is None else profile
    header = RunHeader(
        protocol.name if protocol else "test",
        protocol.text if protocol else "# test",
        "",
        "sphere10mm",
        "",
        "rgb",
        mm_per_px,
        1.0,
        n,
        (1.0, 2.0, 3.0, 0.0),
        tuple(phases),
        sensor_profile=record,
        object_file_toml=object_file,
        object_photo_sha256="ab" * 32 if object_file else "",
    )
    rng = np.random.default_rng(seed)
    frames = rng.integers(20, 230, (n + 1, size, size, 3), dtype=np.uint8)
    if varied:  # frames of growing entropy: compressed chunks of many lengths
        frames = np.stack([rng.integers(20, 22 + 5 * i, (size, size, 3), dtype=np.uint8) for i in range(n + 1)])
    reference = np.random.default_rng(99).integers(20, 230, (size, size, 3), dtype=np.uint8)  # one sensor's
    image = get_indenter("sphere10mm").object_image(size, 14 / size)
    w = RunWriter.create(path, header, (size, size, 3), image, reference, codec=codec)
    for i in range(n if written is None else written):
        row = S.blank_row() | {
            S.WRENCH: rng.normal(size=6),
            S.POSE_MEASURED: np.array([0.05 * i, 0.0, -0.5, 0.0]),
            S.T_FRAME: t0 + i,
            S.T_CAPTURE: float(i),
            S.CAPTURE_INDEX: i,
            S.PHASE_INDEX: list(phases).index(phase),
            S.LEVEL: 1,
        }
        stream = np.column_stack([np.linspace(t0 + i - 0.9, t0 + i, samples), rng.normal(size=(samples, 6))])
        w.append(frames[i], stream=stream, **row)
    if close:
        w.set_status("complete", "")
        w.close()
    else:  # as a kill -9 leaves it: flushed, status running, the lock released by the kernel
        w.f.flush()
        w.f.close()
        w.lock.release()
    return path


def flip(path: Path, at: int) -> None:
    data = bytearray(path.read_bytes())
    data[at] ^= 0x5A
    path.write_bytes(bytes(data))


def chunk_index_byte(path: Path, name: str) -> int:
    """A byte inside dataset ``name``'s chunk index (the header of its extensible array, HDF5's
    "EAHD" block): each such block is flipped in a copy until only that dataset's chunks cannot be listed."""
    data = path.read_bytes()
    probe = path.with_name(path.name + ".probe")
    at = data.find(b"EAHD")
    while at >= 0:
        copy = bytearray(data)
        copy[at + 6] ^= 0x5A  # the element size, inside the checksummed header
        probe.write_bytes(bytes(copy))
        try:
            with h5py.File(probe, "r") as f:
                f[name].id.chunk_iter(lambda info: None)
        except RuntimeError:
            return at + 6
        finally:
            probe.unlink()
        at = data.find(b"EAHD", at + 4)
    raise AssertionError(f"{path}: no chunk index of {name} found")


def chunk_middle(path: Path, name: str, index: int) -> int:
    """The middle byte of chunk ``index`` (negative: from the end) of a dataset's chunks on disk."""
    with h5py.File(path, "r") as f:
        d = f[name].id
        info = d.get_chunk_info(index % d.get_num_chunks())
    return info.byte_offset + info.size // 2


def one_error(result) -> str:
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output and isinstance(result.exception, SystemExit), result.output
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.output
    return errors[0]


# -- the chunk checksum ------------------------------------------------------------------


def test_the_chunk_checksum_agrees_with_hdf5_on_every_chunk_and_finds_each_flip(tmp_path):
    """Compressed chunks of every length (odd ones included) pass; one flipped bit anywhere in a
    chunk, checksum bytes included, fails, as HDF5's own read of it does."""
    path = write_run(tmp_path / "run.h5", n=40, varied=True)
    with h5py.File(path, "r") as f:
        d = f[S.FRAMES]
        raws = [d.id.read_direct_chunk((i, 0, 0, 0))[1] for i in range(40)]
        assert list(bad_chunks(d, 40)) == []
    assert {len(r) % 2 for r in raws} == {0, 1}  # both parities were checked
    assert all(checksum_ok(r) for r in raws)
    rng = np.random.default_rng(1)
    for raw in raws[:8]:
        for at in rng.integers(0, len(raw), 5):
            bad = bytearray(raw)
            bad[at] ^= 1 << int(rng.integers(0, 8))
            assert not checksum_ok(bytes(bad))
    flip(path, chunk_middle(path, S.FRAMES, 7))
    with h5py.File(path, "r") as f:
        assert [lo for lo, _, _ in bad_chunks(f[S.FRAMES], 40)] == [7]
        with pytest.raises(OSError):
            f[S.FRAMES][7]  # HDF5 agrees


def test_a_frame_read_names_the_file_and_the_frame(tmp_path):
    """Every frame is verified when a run is opened (issue 36: `info` and `preview` read none, and
    passed a damaged one); a frame damaged after the run was opened still fails its own read."""
    path = write_run(tmp_path / "run.h5")
    with RunReader.open(path) as run:  # sound: it opens
        flip(path, chunk_middle(path, S.FRAMES, 4))  # damaged while it is open
        run.frame(3)
        with pytest.raises(RunFileError, match=rf"^{path}: frames\[4\]: checksum mismatch"):
            run.frame(4)
    with pytest.raises(RunFileError, match=rf"^{path}: frames\[4\]: checksum mismatch \(its bytes changed on disk\)"):
        RunReader.open(path)


def test_images_are_checksummed_too(tmp_path):
    path = write_run(tmp_path / "run.h5")
    with h5py.File(path, "r") as f:
        assert f[S.OBJECT_IMAGE].fletcher32 and f[S.REFERENCE_FRAME].fletcher32
        info = f[S.OBJECT_IMAGE].id.get_chunk_info(0)
    flip(path, info.byte_offset + 100)
    with pytest.raises(RunFileError, match=rf"{path}: object/image: unreadable"):
        RunReader.open(path)
    assert any(line.startswith("object/image: unreadable") for line in validate(path))


# -- resume ----------------------------------------------------------------------------------


def test_resume_of_a_crashed_run_drops_a_damaged_last_frame_but_refuses_a_damaged_middle_one(tmp_path):
    """A crash can leave the last frame's chunk cut short: dropped, as before. The same damage in
    an earlier frame (followed by sound ones) is damage, not a crash: refused, naming the frame."""
    tail = write_run(tmp_path / "tail.h5", close=False)
    flip(tail, chunk_middle(tail, S.FRAMES, 11))
    w = RunWriter.reopen(tail)
    assert w.n == 11
    w.close()
    middle = write_run(tmp_path / "middle.h5", close=False)
    flip(middle, chunk_middle(middle, S.FRAMES, 5))
    with pytest.raises(RunFileError, match=r"middle.h5: frames\[5\]: checksum mismatch.*cannot resume"):
        RunWriter.reopen(middle)
    closed = write_run(tmp_path / "closed.h5")  # a closed run: its last frame was committed
    flip(closed, chunk_middle(closed, S.FRAMES, 11))
    with pytest.raises(RunFileError, match=r"closed.h5: frames\[11\]: checksum mismatch.*cannot resume"):
        RunWriter.reopen(closed)
    assert not list(tmp_path.glob("*.lock"))  # every refusal released the lock


# -- merge -----------------------------------------------------------------------------------


def test_merge_of_two_good_runs_validates_with_time_increasing_and_every_field(tmp_path):
    """Before: a merge of two good runs failed validate (t_frame_s not increasing) and dropped the
    stream, the profile and the object file's attributes."""
    a = write_run(tmp_path / "a.h5", seed=0, object_file="[object]\nname = 'x'\n")
    b = write_run(
        tmp_path / "b.h5", seed=1, phases=tuple(reversed(PHASES)), phase="shear", object_file="[object]\nname = 'x'\n"
    )
    out = tmp_path / "ab.h5"
    result = runner.invoke(dataset_app, ["merge", str(a), str(b), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert validate(out) == []
    with RunReader.open(out) as m, RunReader.open(a) as ra, RunReader.open(b) as rb:
        assert m.n == 24 and np.all(np.diff(m.rows[S.T_FRAME]) > 0) and np.all(np.diff(m.rows[S.T_CAPTURE]) > 0)
        assert np.array_equal(m.rows[S.CAPTURE_INDEX], np.arange(24))
        assert np.array_equal(m.rows[S.WRENCH], np.concatenate([ra.rows[S.WRENCH], rb.rows[S.WRENCH]]))
        names = [m.phases[k] for k in m.rows[S.PHASE_INDEX]]
        assert names == ["press"] * 12 + ["shear"] * 12  # re-encoded by name, never clipped
        assert np.array_equal(m.frame(13), rb.frame(1))
        # b's time shifted by one offset for frames and stream: its first frame at least one period after
        # a's last, its first stream sample one period after a's last (b's stream starts 0.9 s before its frame)
        assert m.rows[S.T_FRAME][12] == pytest.approx(ra.stream[-1, 0] + 1.0 + 0.9)
        assert m.rows[S.T_FRAME][12] >= ra.rows[S.T_FRAME][-1] + 1.0
        assert len(m.stream) == len(ra.stream) + len(rb.stream) and np.all(np.diff(m.stream[:, 0]) >= 0)
        offset = m.rows[S.T_FRAME][12] - rb.rows[S.T_FRAME][0]
        assert np.allclose(m.stream[len(ra.stream) :, 0] - rb.stream[:, 0], offset)
        for attr in (S.ATTR_SENSOR_PROFILE, S.ATTR_OBJECT_FILE, S.ATTR_OBJECT_PHOTO_SHA256, S.ATTR_OBJECT):
            assert m.text(attr) == ra.text(attr) != ""
        assert "merged from" in m.text(S.ATTR_RIG_CONFIG) and "t_capture_s" in m.text(S.ATTR_RIG_CONFIG)


def test_merge_refuses_runs_of_another_scale_or_profile_and_leaves_nothing(tmp_path):
    a = write_run(tmp_path / "a.h5")
    other_scale = write_run(tmp_path / "scale.h5", mm_per_px=0.06)
    no_profile = write_run(tmp_path / "none.h5", profile="")
    for b, word in ((other_scale, "mm_per_px"), (no_profile, "sensor_profile")):
        out = tmp_path / "ab.h5"
        error = one_error(runner.invoke(dataset_app, ["merge", str(a), str(b), "--out", str(out)]))
        assert word in error and str(b) in error, error
        assert not out.exists() and not list(tmp_path.glob("ab.h5*"))
    error = one_error(runner.invoke(dataset_app, ["merge", str(a), str(a), "--out", str(tmp_path / "no/ab.h5")]))
    assert f"the folder {tmp_path / 'no'} does not exist" in error


# -- import ----------------------------------------------------------------------------------


@pytest.fixture
def folder(tmp_path) -> Path:
    """An exported run: a folder in the import format."""
    export_run(write_run(tmp_path / "src.h5", n=20), tmp_path / "folder")
    return tmp_path / "folder"


def _rows(folder: Path) -> tuple[list[str], list[list[str]]]:
    with open(folder / "frames.csv", newline="") as fh:
        table = list(csv.reader(fh))
    return table[0], table[1:]


def _write_rows(folder: Path, header, rows, prefix: str = "") -> None:
    with open(folder / "frames.csv", "w", newline="", encoding="utf-8") as fh:
        fh.write(prefix)
        csv.writer(fh).writerows([header, *rows])


def _import(folder: Path, out: Path, *extra: str):
    return runner.invoke(dataset_app, ["import", str(folder), "--out", str(out), *extra])


def test_a_row_missing_cells_is_refused_naming_it_and_nothing_is_written(folder, tmp_path):
    """Before: row 19 lacking 4 columns imported with step 0, phase press and level 0 filled in."""
    header, rows = _rows(folder)
    rows[17] = rows[17][:-4]  # frames.csv row 19 (the header is row 1)
    _write_rows(folder, header, rows)
    out = tmp_path / "out.h5"
    error = one_error(_import(folder, out))
    assert "frames.csv: row 19 has" in error and "missing" in error and "level" in error, error
    assert not out.exists() and not list(tmp_path.glob("out.h5*"))
    rows[17] = rows[17] + ["", "", "", ""]  # the cells there, but empty: also refused
    _write_rows(folder, header, rows)
    assert "row 19, column" in one_error(_import(folder, out)) and not out.exists()


def test_unknown_columns_are_refused_unless_ignored(folder, tmp_path):
    header, rows = _rows(folder)
    _write_rows(folder, [*header, "temperature_C"], [[*r, "21.5"] for r in rows])
    error = one_error(_import(folder, tmp_path / "a.h5"))
    assert "unknown column(s) temperature_C" in error and "--ignore-columns" in error, error
    result = _import(folder, tmp_path / "b.h5", "--ignore-columns", "temperature_C")
    assert result.exit_code == 0, result.output
    assert validate(tmp_path / "b.h5") == []
    with RunReader.open(tmp_path / "b.h5") as run:
        assert "columns ignored: temperature_C" in run.text(S.ATTR_RIG_CONFIG)


def test_a_byte_order_mark_is_read_and_the_import_round_trips(folder, tmp_path):
    """Before: a CSV saved with a BOM (Excel's "CSV UTF-8") failed with `missing column(s) file`."""
    header, rows = _rows(folder)
    _write_rows(folder, header, rows, prefix="\ufeff")
    out = tmp_path / "bom.h5"
    result = _import(folder, out)
    assert result.exit_code == 0, result.output
    with RunReader.open(out) as a, RunReader.open(tmp_path / "src.h5") as b:
        for fl in S.PER_FRAME_FIELDS:
            assert np.array_equal(a.rows[fl.path], b.rows[fl.path]), fl.path
        assert a.sensor_profile == b.sensor_profile != ""  # the exported run's own profile came back with it


@pytest.mark.parametrize("damage", ["missing png", "another size"])
def test_a_refused_import_leaves_nothing_behind(folder, tmp_path, damage):
    """Before: a missing PNG or a frame of another size left a 50- or 7-frame `aborted` file."""
    if damage == "missing png":
        (folder / "frames" / "000015.png").unlink()
    else:
        cv2.imwrite(str(folder / "frames" / "000015.png"), np.zeros((16, 16, 3), np.uint8) + 90)
    out = tmp_path / "out.h5"
    error = one_error(_import(folder, out))
    assert "000015.png" in error, error
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["folder", "src.h5"]


def test_import_into_a_missing_folder_names_it(folder, tmp_path):
    """Before: `cannot create its writer lock runs/all.h5.lock (No such file or directory)`."""
    error = one_error(_import(folder, tmp_path / "runs" / "all.h5"))
    assert f"the folder {tmp_path / 'runs'} does not exist" in error, error
    assert not (tmp_path / "runs").exists()


# -- read-only output folders ------------------------------------------------------------------

READ_ONLY = """
set -e
mkdir -p {ro}
mount -t tmpfs -o ro,size=1m tmpfs {ro}
{dataset} split 8:2 {run} --out {ro}/split > {log}/split.out 2>&1 || echo "split rc=$?" >> {log}/rc
{dataset} export {run} --out {ro}/exp > {log}/export.out 2>&1 || echo "export rc=$?" >> {log}/rc
{dataset} preview {run} --out {ro}/sheet.png > {log}/preview.out 2>&1 || echo "preview rc=$?" >> {log}/rc
touch {ro}/probe 2> {log}/probe.err || echo "probe rc=$?" >> {log}/rc
"""


def test_split_and_export_into_a_read_only_folder_are_one_line(tmp_path):
    """Before: `OSError: [Errno 30] Read-only file system` tracebacks. Root writes through chmod, so
    the folder is a read-only tmpfs mounted in a user namespace (a real EROFS from the kernel)."""
    run = write_run(tmp_path / "run.h5")
    if not user_namespaces():
        if os.geteuid() == 0:
            pytest.skip("no user namespaces here to mount a read-only tmpfs, and root writes through chmod")
        ro = tmp_path / "ro"  # not root: the mode bits hold
        ro.mkdir(mode=0o555)
        for args in (
            ["split", "8:2", str(run), "--out", str(ro / "split")],
            ["export", str(run), "--out", str(ro / "x")],
        ):
            error = one_error(runner.invoke(dataset_app, args))
            assert str(ro) in error and "Permission denied" in error, error
        return
    log = tmp_path / "log"
    log.mkdir()
    script = READ_ONLY.format(ro=tmp_path / "ro", dataset=Path(sys.executable).parent / "dataset", run=run, log=log)
    proc = subprocess.run(
        ["unshare", "--user", "--map-root-user", "--mount", "sh", "-c", script],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert proc.returncode == 0, proc.stderr
    rc = (log / "rc").read_text()
    assert "probe rc=1" in rc and "Read-only file system" in (log / "probe.err").read_text()  # truly read-only
    for name in ("split", "export", "preview"):
        assert f"{name} rc=1" in rc, rc
        text = (log / f"{name}.out").read_text()
        assert "Traceback" not in text and len(text.strip().splitlines()) == 1, text
        assert text.startswith("error: --out ") and str(tmp_path / "ro") in text and "Read-only" in text, text


# -- sensor profiles -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def unprofiled(tmp_path_factory):
    """A split of a run that records no sensor profile, and a tiny model trained on it without physics."""
    root = tmp_path_factory.mktemp("unprofiled")
    write_run(root / "real.h5", n=24, profile="")
    make_split([root / "real.h5"], "8:2", root / "split")
    result = runner.invoke(
        train_app,
        ["--data", str(root / "split"), "--out", str(root / "model"), "--image-size", "16", "--steps", "1"]
        + ["--batch-size", "4", "--sample-every", "0", "--conditioning", "plane+embedding", "--threads", "1"],
    )
    assert result.exit_code == 0, result.output
    return root


def test_dataset_info_prints_the_profile_or_that_there_is_none(unprofiled, tmp_path):
    none = runner.invoke(dataset_app, ["info", str(unprofiled / "real.h5")])
    assert "sensor profile: none recorded" in none.output and "--profile" in none.output, none.output
    shipped = runner.invoke(dataset_app, ["info", str(write_run(tmp_path / "sim.h5"))])
    assert f"sensor profile: {default_profile().name} (sha256 {default_profile().content_hash()[:12]}" in shipped.output


def test_a_run_without_a_profile_is_refused_by_evaluates_physics_row(unprofiled, tmp_path):
    """Before: rendered through the shipped GelSight Mini profile (physics MSE 487.7 where the right
    profile gives 17.2), saying only "with each run's sensor profile"."""
    args = ["--checkpoint", str(unprofiled / "model"), "--split", str(unprofiled / "split")]
    args += ["--settings", "ddim:1", "--limit", "2", "--no-force-sweep", "--threads", "1"]
    error = one_error(runner.invoke(evaluate_app, [*args, "--out", str(tmp_path / "a")]))
    assert "real.h5: records no sensor profile" in error and "--profile" in error, error
    assert not (tmp_path / "a").exists()
    given = runner.invoke(evaluate_app, [*args, "--out", str(tmp_path / "b"), "--profile", str(default_profile().path)])
    assert given.exit_code == 0, given.output
    report = (tmp_path / "b" / "report.md").read_text()
    assert f"`real.h5`: {default_profile().name}" in report and "given by --profile" in report, report
    metrics = json.loads((tmp_path / "b" / "metrics.json").read_text())
    assert "given by --profile" in next(iter(metrics["parts"]["test"]["physics_render_profiles"].values()))
    skipped = runner.invoke(evaluate_app, [*args, "--out", str(tmp_path / "c"), "--no-baseline"])
    assert skipped.exit_code == 0, skipped.output


def test_a_run_without_a_profile_is_refused_by_physics_training(unprofiled, tmp_path):
    base = ["--data", str(unprofiled / "split"), "--image-size", "16", "--steps", "1", "--batch-size", "4"]
    base += ["--sample-every", "0", "--threads", "1"]
    error = one_error(
        runner.invoke(train_app, [*base, "--out", str(tmp_path / "a"), "--conditioning", "physics+plane"])
    )
    assert "real.h5: records no sensor profile" in error and "train --profile FILE" in error, error
    default = runner.invoke(train_app, [*base, "--out", str(tmp_path / "b")])  # rgb's default is physics
    assert default.exit_code == 0 and "conditioning plane+embedding, not the default physics" in default.output
    assert "records no sensor profile" in default.output, default.output
    given = runner.invoke(
        train_app,
        [
            *base,
            "--out",
            str(tmp_path / "c"),
            "--conditioning",
            "physics+plane",
            "--profile",
            str(default_profile().path),
        ],
    )
    assert given.exit_code == 0, given.output
    meta = json.loads((tmp_path / "c" / "checkpoint" / "state.json").read_text())
    assert meta["physics"]["profile_record"] == default_profile().record()


# -- splits and messages ---------------------------------------------------------------------------


def test_a_broken_or_old_split_json_is_one_line_naming_it(tmp_path):
    run = write_run(tmp_path / "run.h5", n=12)
    make_split([run], "8:2", tmp_path / "s")
    manifest = tmp_path / "s" / "split.json"
    good = manifest.read_text()
    manifest.write_text(good[:-20])
    args = ["--data", str(tmp_path / "s"), "--out", str(tmp_path / "m"), "--steps", "1"]
    error = one_error(runner.invoke(train_app, args))
    assert f"{manifest}: not valid JSON (line" in error, error
    old = json.loads(good)
    del old["runs"][0]["identity"]
    manifest.write_text(json.dumps(old))
    error = one_error(runner.invoke(train_app, args))
    assert "[runs][0].identity: missing" in error and "make it again" in error, error


def test_validate_of_a_file_without_frames_names_it(tmp_path):
    """Before: `cannot reshape array of size 0`."""
    path = write_run(tmp_path / "run.h5")
    with h5py.File(path, "r+") as f:
        del f[S.FRAMES]
    findings = validate(path)
    assert "frames: missing" in findings and not any("reshape" in line for line in findings), findings


def test_calibrate_and_view_refuse_a_file_that_is_not_a_run_in_one_line(tmp_path):
    """Before: `rig sensor calibrate notrun.h5` was a RunFileError traceback."""
    for name, content in (("notrun.h5", b"hello"), ("empty.h5", b"")):
        path = tmp_path / name
        path.write_bytes(content)
        error = one_error(runner.invoke(rig_app, ["sensor", "calibrate", str(path), "--out", str(tmp_path / "p.toml")]))
        assert str(path) in error, error
        assert str(path) in one_error(runner.invoke(dataset_app, ["view", str(path)]))
    cut = write_run(tmp_path / "cut.h5")
    cut.write_bytes(cut.read_bytes()[:5000])
    error = one_error(runner.invoke(rig_app, ["sensor", "calibrate", str(cut), "--out", str(tmp_path / "p.toml")]))
    assert "truncated" in error, error


def test_model_values_and_poses_are_named(tmp_path):
    """Before: `[model] not all arguments converted during string formatting` for image_size "many",
    and `generate --pose 1e30` answered `Fz 1 N is beyond …`."""
    from model.denoiser.config import ModelConfig

    with pytest.raises(ValueError, match="image_size must be a whole number > 0, got 'many'"):
        ModelConfig(image_size="many")
    state = tmp_path / "m" / "checkpoint"
    state.mkdir(parents=True)
    (state / "state.json").write_text(json.dumps({"step": 1, "model": {"image_size": "many"}}))
    args = ["--checkpoint", str(tmp_path / "m"), "--object", "sphere10mm", "--wrench", "0,0,1,0,0,0"]
    error = one_error(runner.invoke(generate_app, [*args, "--out", str(tmp_path / "x.png")]))
    assert "[model] image_size must be a whole number > 0, got 'many'" in error, error
    result = runner.invoke(generate_app, [*args, "--pose", "1e30,0,0", "--out", str(tmp_path / "x.png")])
    assert result.exit_code == 2 and "--pose: value 1 is 1e+30" in result.output, result.output


@pytest.mark.parametrize(
    "edit,words",
    [
        (lambda f: f.attrs.__setitem__(S.ATTR_FRAMES_PLANNED, "many"), "attribute frames_planned: is 'many'"),
        (lambda f: f[S.STATUS].__setitem__((), np.bytes_(b"\xff\xfeok")), "run/status: not UTF-8 text"),
        (lambda f: f[S.STATUS].__setitem__((), np.bytes_(b"finished")), "run/status: 'finished' is not one of"),
    ],
)
def test_attributes_and_text_outside_the_schema_are_named(tmp_path, edit, words):
    """Before: `invalid literal for int() ... 'many'` and `'utf-8' codec can't decode` from merge."""
    a, b = write_run(tmp_path / "a.h5"), write_run(tmp_path / "b.h5", seed=1)
    with h5py.File(a, "r+") as f:
        edit(f)
    for args in (["info", str(a)], ["merge", str(a), str(b), "--out", str(tmp_path / "ab.h5")]):
        error = one_error(runner.invoke(dataset_app, args))
        assert f"{a}: " in error and words in error, error
    assert any(words.split(": ", 1)[1] in line for line in validate(a)), validate(a)
