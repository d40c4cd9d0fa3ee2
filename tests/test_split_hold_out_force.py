"""`dataset split --hold-out-top Fz:N`: the N hardest presses form the part test_force, never trained on,
and evaluation and compare report on it."""

import json

import numpy as np
import pytest

from tests.test_model_core import SMALL, write_run

SIZE = 16


def fz_run(path, obj, fz, seed=0):
    """A run of library object ``obj`` with one frame per value of ``fz`` (N), random pictures, z deeper with Fz."""
    rng = np.random.default_rng(seed)
    rows = []
    for value in fz:
        frame = rng.integers(0, 256, (SIZE, SIZE, 3), dtype=np.uint8)
        wrench = np.array([0.1 * rng.normal(), 0.1 * rng.normal(), value, 0.0, 0.0, 0.01 * rng.normal()])
        rows.append((frame, wrench, np.zeros(4), np.array([0.0, 0.0, -0.1 * value, 0.0])))
    return write_run(path, obj, rows, reference=np.full((SIZE, SIZE, 3), 128, np.uint8))


FZ_A = np.linspace(0.2, 2.0, 15)[np.random.default_rng(5).permutation(15)]  # 0.2 … 2.0 N in a shuffled order
FZ_B = np.linspace(0.25, 2.65, 13)[np.random.default_rng(6).permutation(13)]


@pytest.fixture
def runs(tmp_path):
    return [
        fz_run(tmp_path / "sphere10mm.h5", "sphere10mm", FZ_A),
        fz_run(tmp_path / "square.h5", "square", FZ_B, seed=1),
    ]


def _fz(manifest, rows):
    from acquisition import schema as S
    from dataset.runs import open_run

    out = []
    for run, frame in rows:
        with open_run(manifest["runs"][int(run)]["path"]) as r:
            out.append(float(r.rows[S.WRENCH][int(frame), 2]))
    return np.array(out)


def test_the_held_out_frames_are_exactly_the_top_n_by_fz_and_none_leak(runs, tmp_path):
    from dataset.split import load_split, make_split

    s = make_split(runs, "8:2", tmp_path / "s", hold_out_top="Fz:5")
    manifest, parts = load_split(tmp_path / "s")
    assert set(parts) == {"train", "test", "test_force"}
    every = np.concatenate([FZ_A, FZ_B])
    top5 = np.sort(every)[-5:]
    held = _fz(manifest, parts["test_force"])
    assert np.allclose(np.sort(held), top5)
    # the rest is split 8:2 as usual, and no frame is in two parts
    assert len(parts["train"]) + len(parts["test"]) == len(every) - 5 and len(parts["test"]) == 5
    seen = [tuple(r) for p in parts.values() for r in p]
    assert len(seen) == len(set(seen)) == len(every)
    for name in ("train", "test"):
        assert _fz(manifest, parts[name]).max() < top5.min(), name
    record = manifest["held_out_top"]
    assert record["part"] == "test_force" and record["component"] == "Fz" and record["frames"] == 5
    assert record["unit"] == "N" and record["largest_held_out"] == pytest.approx(2.65)
    assert record["smallest_held_out"] == pytest.approx(top5.min())
    assert record["largest_kept"] == pytest.approx(np.sort(every)[-6])
    # the training statistics and the sweep's range come from the training part only
    assert manifest["wrench_percentiles"]["p98"][2] < top5.min()
    assert s.wrench_mean[2] == pytest.approx(_fz(manifest, parts["train"]).mean())
    # a moment component, in any case, and a plain split has no held_out_top record
    make_split(runs, "8:2", tmp_path / "m", hold_out_top="mz:3")
    assert json.loads((tmp_path / "m" / "split.json").read_text())["held_out_top"]["component"] == "Mz"
    make_split(runs, "8:2", tmp_path / "p")
    assert "held_out_top" not in json.loads((tmp_path / "p" / "split.json").read_text())


def test_with_held_out_objects_and_by_run(runs, tmp_path):
    from dataset.split import load_split, make_split

    make_split(runs, "8:2", tmp_path / "s", hold_out=["square"], hold_out_top="Fz:2")
    manifest, parts = load_split(tmp_path / "s")
    assert set(parts) == {"train", "test", "test_object", "test_force"}
    assert set(parts["test_object"][:, 0]) == {1} and len(parts["test_object"]) == len(FZ_B)
    assert np.allclose(np.sort(_fz(manifest, parts["test_force"])), np.sort(FZ_A)[-2:])  # among the others
    make_split(runs, "1:1", tmp_path / "r", by="run", hold_out_top="Fz:4")
    manifest, parts = load_split(tmp_path / "r")
    assert np.allclose(np.sort(_fz(manifest, parts["test_force"])), np.sort(np.concatenate([FZ_A, FZ_B]))[-4:])
    assert len({int(r) for r in parts["train"][:, 0]} & {int(r) for r in parts["test"][:, 0]}) == 0


@pytest.mark.parametrize(
    ("flag", "message"),
    [
        ("Fz:0", "--hold-out-top 'Fz:0': N must be at least 1, got 0"),
        ("Fz:-2", "--hold-out-top 'Fz:-2': N must be at least 1, got -2"),
        ("Fz:28", "--hold-out-top Fz:28: N must be less than the 28 frame(s) there are to split"),
        (
            "Fz:27",
            "--hold-out-top Fz:27: leaves 1 of the 28 frame(s), too few for the ratio's 2 parts",
        ),  # one frame left: too few for train and test
        ("Fq:3", "--hold-out-top 'Fq:3': unknown wrench component 'Fq'"),
        ("Fz", "--hold-out-top 'Fz': expected COMPONENT:N such as Fz:5"),
        ("Fz:two", "--hold-out-top 'Fz:two': N 'two' is not a whole number"),
        ("Fz:2.5", "N '2.5' is not a whole number"),
    ],
)
def test_bad_flags_give_one_line_errors(runs, tmp_path, flag, message):
    from typer.testing import CliRunner

    from cli.dataset_app import app

    r = CliRunner().invoke(app, ["split", "8:2", *map(str, runs), "--out", str(tmp_path / "s"), "--hold-out-top", flag])
    assert r.exit_code == 1, r.output
    assert message in r.output and "Traceback" not in r.output
    assert len(r.output.strip().splitlines()) == 1, r.output
    assert not (tmp_path / "s" / "split.json").exists()


def test_a_value_that_is_not_finite_is_refused_in_one_line(tmp_path):
    """The verified read refuses a run with a NaN wrench before the split looks at it; the split's own
    check (for any path around that read) names the flag, the run and the frame."""
    from typer.testing import CliRunner

    from cli.dataset_app import app
    from dataset.split import SplitError, _hold_out_top

    path = fz_run(tmp_path / "nan.h5", "sphere10mm", np.array([0.5, 1.0, np.nan, 1.5, 0.7, 0.9]))
    r = CliRunner().invoke(app, ["split", "8:2", str(path), "--out", str(tmp_path / "s"), "--hold-out-top", "Fz:2"])
    assert r.exit_code == 1 and "Traceback" not in r.output and len(r.output.strip().splitlines()) == 1
    assert "NaN/inf" in r.output
    wrench = np.zeros((6, 6))
    wrench[:, 2] = [0.5, 1.0, np.nan, 1.5, 0.7, 0.9]
    rows = np.stack([np.zeros(6, np.int32), np.arange(6, dtype=np.int32)], axis=1)
    with pytest.raises(SplitError, match=r"^--hold-out-top Fz:2: nan\.h5 frame 2 has Fz = nan, not a finite number"):
        _hold_out_top(("Fz", 2), rows, [wrench], ["nan.h5"], 2, warn=print)


def test_a_tie_at_the_cut_is_warned_about_and_broken_by_file_order(tmp_path):
    from dataset.split import _hold_out_top

    wrench = np.zeros((5, 6))
    wrench[:, 2] = [1.0, 2.0, 1.0, 3.0, 0.5]
    rows = np.stack([np.zeros(5, np.int32), np.arange(5, dtype=np.int32)], axis=1)
    said = []
    held, kept, record = _hold_out_top(("Fz", 3), rows, [wrench], ["r.h5"], 2, warn=said.append)
    assert held[:, 1].tolist() == [0, 1, 3] and kept[:, 1].tolist() == [2, 4]
    assert record["smallest_held_out"] == record["largest_kept"] == 1.0
    assert len(said) == 1 and "shared by frames on both sides" in said[0]


def test_split_command_prints_the_part_and_a_hand_edited_record_is_refused(runs, tmp_path):
    from typer.testing import CliRunner

    from cli.dataset_app import app
    from dataset.split import SplitError, load_split

    r = CliRunner().invoke(
        app, ["split", "8:2", *map(str, runs), "--out", str(tmp_path / "s"), "--hold-out-top", "Fz:5"]
    )
    assert r.exit_code == 0, r.output
    assert "test_force 5" in r.output
    assert "held out (test_force): the 5 frame(s) of largest Fz, " in r.output and "–2.65 N" in r.output
    path = tmp_path / "s" / "split.json"
    manifest = json.loads(path.read_text())
    manifest["held_out_top"]["frames"] = 4
    path.write_text(json.dumps(manifest))
    with pytest.raises(SplitError, match=r"\[held_out_top\] says 4 frame\(s\) in part 'test_force', \[parts\] says 5"):
        load_split(tmp_path / "s")


def test_compare_and_evaluation_report_on_the_test_force_part(runs, tmp_path):
    from dataset.split import make_split
    from model.compare.compare import Candidate, compare, summary
    from model.compare.compare_report import write_compare_report

    make_split(runs, "8:2", tmp_path / "s", hold_out_top="Fz:5")
    results = compare(
        [Candidate.parse("plane")],
        [0],
        SMALL,
        {"steps": 2, "batch_size": 4, "checkpoint_every": 100},
        tmp_path / "s",
        tmp_path / "cmp",
        evaluate_kwargs={"settings": (("ddim", 2),), "limit": 2, "baseline": False},
    )
    assert set(results[0].parts) == {"test", "test_force"}
    text = (tmp_path / "cmp" / "plane" / "seed-0" / "report" / "report.md").read_text()
    assert "## Part `test_force`: the frames of largest load held out of training" in text
    assert "held out of training (part test_force)" in text and "the 5 frame(s) of largest Fz" in text
    s = summary(results)
    assert set(s) == {"test", "test_force"} and s["test_force"]["frames"] == 2
    md = write_compare_report(s, tmp_path / "cmp", title="t", context={"split": "split"}).read_text()
    assert "## Part `test_force`" in md
