"""`dataset`: info, validate, split and the training Dataset, on run files written by RunWriter."""

from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from acquisition import schema as S
from acquisition.run_file import RunHeader, RunWriter
from cli.dataset_app import app
from dataset.condition import place_object
from dataset.runs import summarize, validate
from dataset.split import SplitError, load_split, make_split, parse_ratios
from objects.indenters import get_indenter
from protocols.plan import PHASES

runner = CliRunner()


def make_run(
    path: Path,
    n: int = 40,
    *,
    obj: str = "sphere10mm",
    status: str = "complete",
    size: int = 64,
    seed: int = 0,
    wrench_offset: float = 0.0,
) -> Path:
    rng = np.random.default_rng(seed)
    header = RunHeader("test", f"# {obj}", "", obj, "", "rgb", 14 / size, 1.0, n, (0, 0, 0, 0), PHASES)
    frames = rng.integers(20, 230, (n, size, size, 3), dtype=np.uint8)
    reference = np.random.default_rng(99).integers(20, 230, (size, size, 3), dtype=np.uint8)  # one sensor's
    w = RunWriter.create(path, header, (size, size, 3), get_indenter(obj).object_image(size, 14 / size), reference)
    for i in range(n):
        w.append(
            frames[i],
            wrench=rng.normal(size=6) + wrench_offset,
            pose_commanded=np.zeros(4),
            pose_measured=np.array([0.5, -0.25, -1.0, 0.0]),
            t_frame_s=float(i),
            t_capture_s=float(i),
            wrench_skew_s=0.001,
            capture_index=i,
            step_index=0,
            phase_index=1,
            level=1,
            retake=0,
        )
    w.set_status(status, "" if status == "complete" else "force limit: Fz = 9 N")
    w.close()
    return path


@pytest.fixture
def runs(tmp_path):
    return [
        make_run(tmp_path / f"run{i}.h5", n=30 + 10 * i, obj=obj, seed=i)
        for i, obj in enumerate(["sphere10mm", "sphere10mm", "heart", "ring"])
    ]


def test_ratios():
    assert parse_ratios("8:2") == (0.8, 0.2)
    assert parse_ratios("7:1:2") == pytest.approx((0.7, 0.1, 0.2))
    for bad in ("8", "8:x", "-1:2", "1:1:1:1"):
        with pytest.raises(SplitError):
            parse_ratios(bad)


@pytest.mark.parametrize("ratio", ["8:2", "7:1:2"])
def test_frame_split_is_reproducible_disjoint_and_complete(runs, tmp_path, ratio):
    a = make_split(runs, ratio, tmp_path / "a", seed=3)
    b = make_split(runs, ratio, tmp_path / "b", seed=3)
    c = make_split(runs, ratio, tmp_path / "c", seed=4)
    for name in a.parts:
        np.testing.assert_array_equal(a.parts[name], b.parts[name])
    assert any(not np.array_equal(a.parts[k], c.parts[k]) for k in a.parts)
    rows = np.concatenate(list(a.parts.values()))
    total = sum(summarize(r).frames for r in runs)
    assert len(rows) == total and len({tuple(r) for r in rows}) == total  # every frame, once
    fractions = [len(v) / total for v in a.parts.values()]
    assert fractions == pytest.approx(parse_ratios(ratio), abs=1 / total + 1e-9)


@pytest.mark.parametrize("by", ["run", "object"])
def test_grouped_split_never_shares(runs, tmp_path, by):
    make_split(runs, "1:1", tmp_path / by, seed=1, by=by)
    manifest, parts = load_split(tmp_path / by)
    key = (lambda r: manifest["runs"][r]["path"]) if by == "run" else (lambda r: manifest["runs"][r]["object"])
    train = {key(r) for r in parts["train"][:, 0]}
    test = {key(r) for r in parts["test"][:, 0]}
    assert train and test and not train & test
    assert len(parts["train"]) + len(parts["test"]) == sum(summarize(r).frames for r in runs)


def test_wrench_statistics_come_from_train_only(tmp_path):
    a = make_run(tmp_path / "a.h5", n=50, obj="heart", wrench_offset=0.0)
    b = make_run(tmp_path / "b.h5", n=50, obj="ring", wrench_offset=100.0, seed=1)
    s = make_split([a, b], "1:1", tmp_path / "s", by="object", seed=0)
    train_obj = {summarize([a, b][r]).object_name for r in s.parts["train"][:, 0]}
    expected = 100.0 if train_obj == {"ring"} else 0.0
    assert np.mean(s.wrench_mean) == pytest.approx(expected, abs=0.5)


def test_aborted_run_is_an_error_or_a_warning(tmp_path):
    bad = make_run(tmp_path / "aborted.h5", status="aborted")
    result = runner.invoke(app, ["split", "8:2", str(bad), "--out", str(tmp_path / "s")])
    assert result.exit_code == 1 and "aborted.h5: run is aborted" in result.output and "Traceback" not in result.output
    result = runner.invoke(app, ["split", "8:2", str(bad), "--out", str(tmp_path / "s"), "--allow-incomplete"])
    assert result.exit_code == 0 and "warning" in result.output


def test_bad_files_get_one_line_errors(tmp_path, runs):
    not_hdf5 = tmp_path / "notes.h5"
    not_hdf5.write_text("hello")
    empty = tmp_path / "empty.h5"
    with h5py.File(empty, "w") as f:
        f.create_dataset("frames", data=np.zeros((1, 4, 4, 3), np.uint8))
    small = make_run(tmp_path / "small.h5", size=32)
    cases = [
        (["info", str(not_hdf5)], "notes.h5: not an HDF5 file"),
        (["info", str(tmp_path / "missing.h5")], "missing.h5: no such file"),
        (["info", str(empty)], "empty.h5: not a run file: missing wrench"),
        (["split", "8:2", str(runs[0]), str(small), "--out", str(tmp_path / "s")], "frame sizes differ"),
    ]
    for args, words in cases:
        result = runner.invoke(app, args)
        assert result.exit_code == 1 and words in result.output and "Traceback" not in result.output, result.output


def test_validate_finds_problems(tmp_path):
    good = make_run(tmp_path / "good.h5")
    assert validate(good) == []
    broken = make_run(tmp_path / "broken.h5")
    with h5py.File(broken, "r+") as f:
        f[S.WRENCH][3, 2] = np.nan
        f[S.T_FRAME][10] = 2.0
        f[S.FRAMES][0] = 0
        f[S.WRENCH_SKEW][5] = 0.5
    findings = "\n".join(validate(broken))
    for words in (
        "wrench: NaN/inf in 1 rows (first at frame 3)",
        "t_frame_s: not increasing",
        "frames[0]: all black",
        "wrench_skew_s: 1 frames beyond 0.1 s",
        # rows and a frame rewritten after the run: their identity digests no longer match (frame_identity.py)
        "frames[0]: not the frame written at this index (its identity digest differs: rewritten, moved, swapped or "
        "copied) and 3 more",
    ):
        assert words in findings
    result = runner.invoke(app, ["validate", str(good), str(broken)])
    assert result.exit_code == 1 and "good.h5: ok" in result.output and "broken.h5: 5 finding(s)" in result.output


def test_info_reports_runs(runs):
    result = runner.invoke(app, ["info", str(runs[2])])
    assert result.exit_code == 0 and "50/50 frames 64x64, complete" in result.output and "object heart" in result.output


def test_object_placed_at_the_pose():
    img = np.zeros((101, 101, 3), np.uint8)
    img[50, 50] = 255
    moved = place_object(img, 1.0, 0.5, 0.0, mm_per_px=0.1)  # +10 px right, +5 px up
    assert np.unravel_index(moved[..., 0].argmax(), moved.shape[:2]) == (45, 60)
    img[50, 70] = 200
    turned = place_object(img, 0.0, 0.0, 90.0, mm_per_px=0.1)  # +90°: a point on +x goes to +y (up)
    ys, xs = np.nonzero(turned[..., 0] > 100)
    assert (30, 50) in set(zip(ys.tolist(), xs.tolist()))


def test_torch_dataset_and_workers(runs, tmp_path):
    import torch
    from torch.utils.data import DataLoader

    from dataset.torch_dataset import TactileDataset, to_model_inputs

    make_split(runs, "8:2", tmp_path / "s", seed=0)
    ds = TactileDataset(tmp_path / "s", "train", size=32)
    item = ds[0]
    assert item["condition"].shape == item["tactile"].shape == (3, 32, 32) and item["tactile"].dtype == torch.uint8
    assert item["wrench"].shape == (6,)
    loader = DataLoader(ds, batch_size=8, num_workers=2)
    batch = to_model_inputs(next(iter(loader)))
    assert batch["tactile"].shape == (8, 3, 32, 32) and -1.0 <= batch["tactile"].min() <= batch["tactile"].max() <= 1.0
    with pytest.raises(KeyError, match="val"):
        TactileDataset(tmp_path / "s", "val")


def test_dataset_commands_do_not_import_torch():
    import subprocess
    import sys

    code = (
        "import sys; from cli.dataset_app import app; import dataset.runs, dataset.split; print('torch' in sys.modules)"
    )
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.strip() == "False"


def test_export_import_round_trip(tmp_path):
    src = make_run(tmp_path / "src.h5", n=12)
    assert runner.invoke(app, ["export", str(src), "--out", str(tmp_path / "folder")]).exit_code == 0
    result = runner.invoke(app, ["import", str(tmp_path / "folder"), "--out", str(tmp_path / "back.h5")])
    assert result.exit_code == 0, result.output
    with h5py.File(src, "r") as a, h5py.File(tmp_path / "back.h5", "r") as b:
        for name in (S.FRAMES, S.WRENCH, S.POSE_MEASURED, S.POSE_COMMANDED, S.T_FRAME, S.OBJECT_IMAGE):
            np.testing.assert_array_equal(a[name][()], b[name][()], err_msg=name)
        assert b.attrs[S.ATTR_MM_PER_PX] == a.attrs[S.ATTR_MM_PER_PX] and b[S.STATUS][()] == b"complete"
    assert validate(tmp_path / "back.h5") == []


def test_import_errors_name_file_row_and_column(tmp_path):
    src = make_run(tmp_path / "src.h5", n=4)
    folder = tmp_path / "folder"
    runner.invoke(app, ["export", str(src), "--out", str(folder)])
    table = folder / "frames.csv"
    text = table.read_text()
    table.write_text(text.replace(text.splitlines()[2].split(",")[4], "heavy", 1))
    result = runner.invoke(app, ["import", str(folder), "--out", str(tmp_path / "x.h5")])
    assert result.exit_code == 1 and "frames.csv: row 3, column Fz_N: 'heavy' is not a number" in result.output
    (folder / "object.png").unlink()
    table.write_text(text)
    result = runner.invoke(app, ["import", str(folder), "--out", str(tmp_path / "y.h5")])
    assert result.exit_code == 1 and "no object.png" in result.output
    table.write_text("file,Fx_N\n")
    result = runner.invoke(app, ["import", str(folder), "--out", str(tmp_path / "z.h5")])
    assert result.exit_code == 1 and "missing column(s) Fy_N" in result.output


def test_merge_like_with_like(tmp_path):
    a = make_run(tmp_path / "a.h5", n=10)
    b = make_run(tmp_path / "b.h5", n=7, seed=1)
    result = runner.invoke(app, ["merge", str(a), str(b), "--out", str(tmp_path / "m.h5")])
    assert result.exit_code == 0 and "17 frames from 2 run(s)" in result.output
    with h5py.File(tmp_path / "m.h5", "r") as m, h5py.File(b, "r") as fb:
        np.testing.assert_array_equal(m[S.CAPTURE_INDEX][:], np.arange(17))
        np.testing.assert_array_equal(m[S.FRAMES][10:], fb[S.FRAMES][:])
    other = make_run(tmp_path / "c.h5", n=5, obj="heart")
    result = runner.invoke(app, ["merge", str(a), str(other), "--out", str(tmp_path / "n.h5")])
    assert result.exit_code == 1 and "differ in object" in result.output


def test_preview_writes_a_contact_sheet(tmp_path):
    import cv2

    src = make_run(tmp_path / "src.h5", n=30)
    result = runner.invoke(app, ["preview", str(src), "--out", str(tmp_path / "p.png"), "--tiles", "12"])
    assert result.exit_code == 0 and "12 frames" in result.output
    sheet = cv2.imread(str(tmp_path / "p.png"))
    assert sheet.shape == (2 * 160, 6 * 160, 3)


def test_info_prints_the_pose_convention(runs):
    result = runner.invoke(app, ["info", str(runs[0])])
    assert result.exit_code == 0
    assert "pose: +x right, +y up in the frame, z negative into the gel, theta counter-clockwise" in result.output
    assert "imported from" not in result.output  # a collected run: nothing was converted


def test_export_states_the_pose_convention_import_requires(tmp_path):
    import json

    from dataset.pose_convention import POSE_CONVENTION

    src = make_run(tmp_path / "src.h5", n=3)
    runner.invoke(app, ["export", str(src), "--out", str(tmp_path / "folder")])
    meta = json.loads((tmp_path / "folder" / "run.json").read_text())
    assert meta["pose_convention"] == POSE_CONVENTION and meta["sensor"] == "rgb"
    del meta["pose_convention"]
    (tmp_path / "folder" / "run.json").write_text(json.dumps(meta))
    result = runner.invoke(app, ["import", str(tmp_path / "folder"), "--out", str(tmp_path / "back.h5")])
    assert result.exit_code == 1 and "[pose_convention] missing" in result.output


# -- splits that say where each run goes (issue 37) ---------------------------------------------
def test_named_test_runs_go_to_test_whatever_the_seed_and_the_split_says_where(tmp_path):
    even = make_run(tmp_path / "even.h5", n=30, seed=0)
    odd = make_run(tmp_path / "odd.h5", n=30, seed=1)
    for seed in (0, 3):
        out = tmp_path / f"s{seed}"
        args = ["split", "1:1", str(even), str(odd), "--out", str(out), "--seed", str(seed), "--by", "run"]
        result = runner.invoke(app, [*args, "--test-runs", str(odd)])
        assert result.exit_code == 0, result.output
        assert f"  {even}: train 30" in result.output and f"  {odd}: test 30" in result.output
        manifest, parts = load_split(out)
        assert manifest["test_runs"] == [str(odd.resolve())]
        assert [r["parts"] for r in manifest["runs"]] == [{"train": 30}, {"test": 30}]
        assert set(parts["test"][:, 0].tolist()) == {1}


def test_a_ratio_whole_runs_cannot_give_is_refused_in_one_line(tmp_path):
    a, b = make_run(tmp_path / "a.h5", n=20), make_run(tmp_path / "b.h5", n=20, seed=1)
    result = runner.invoke(app, ["split", "8:2", str(a), str(b), "--out", str(tmp_path / "s"), "--by", "run"])
    assert result.exit_code == 1 and "8:2 by run: 2 run(s) can only be split 1:1" in result.output, result.output
    assert "--test-runs" in result.output and not (tmp_path / "s").exists()
    # by frame it can: 32 and 8 frames
    assert runner.invoke(app, ["split", "8:2", str(a), str(b), "--out", str(tmp_path / "f")]).exit_code == 0


def test_held_out_runs_form_their_own_part_and_unknown_runs_are_named(tmp_path):
    runs = [make_run(tmp_path / f"r{i}.h5", n=20, seed=i) for i in range(3)]
    make_split(runs, "8:2", tmp_path / "s", hold_out_runs=[runs[2]])
    manifest, parts = load_split(tmp_path / "s")
    assert set(parts["test_run"][:, 0].tolist()) == {2} and 2 not in set(parts["train"][:, 0].tolist())
    with pytest.raises(SplitError, match=r"--test-runs .*nosuch.h5: not one of the runs given"):
        make_split(runs, "8:2", tmp_path / "t", test_runs=[tmp_path / "nosuch.h5"])
    # a run may be named by its file name alone, or its stem, where that names one run
    make_split(runs, "8:2", tmp_path / "n", test_runs=["r1.h5"], hold_out_runs=["r2"])
    _, parts = load_split(tmp_path / "n")
    assert set(parts["test"][:, 0].tolist()) == {1} and set(parts["test_run"][:, 0].tolist()) == {2}
    (tmp_path / "other").mkdir()
    twin = make_run(tmp_path / "other" / "r1.h5", n=20, seed=5)
    with pytest.raises(SplitError, match=r"--test-runs r1.h5: names 2 of the runs given to split .*give its path"):
        make_split([*runs, twin], "8:2", tmp_path / "u", test_runs=["r1.h5"])
