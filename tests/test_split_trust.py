"""A split vouches for its run files only as long as they are what it verified, and says so.

Before: a file whose only change was its modification time (a copy, a restore, `touch`) was refused;
the values split.json holds about each run (object, scale, sensor, profile) were used as written,
an edited split.json included; and `train --profile` silently replaced the profile a run records.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest
from test_verified_reads import chunk_middle, flip, one_error, write_run
from typer.testing import CliRunner

from acquisition import schema as S
from acquisition.run_identity import changed_since
from cli.model_app import app as train_app
from dataset.split import SplitError, check_unchanged, load_split, make_split
from dataset.torch_dataset import TactileDataset
from sensor_sim.profile import default_profile

runner = CliRunner()


def _split(tmp_path: Path, n: int = 12) -> tuple[Path, Path, dict]:
    run = write_run(tmp_path / "run.h5", n=n)
    make_split([run], "8:2", tmp_path / "split")
    manifest, _ = load_split(tmp_path / "split")
    return run, tmp_path / "split", manifest


def test_a_file_whose_only_change_is_its_time_is_accepted(tmp_path):
    run, split, manifest = _split(tmp_path)
    recorded = manifest["runs"][0]["identity"]
    copy = tmp_path / "copy.h5"
    shutil.copyfile(run, copy)  # a copy without -p: a new modification time, the same bytes
    os.replace(copy, run)
    assert os.stat(run).st_mtime_ns != recorded["mtime_ns"]
    assert changed_since(run, recorded) == ""
    check_unchanged(manifest, split)
    assert len(TactileDataset(split, "train", size=16)) == manifest["parts"]["train"]


def test_a_byte_changed_inside_a_frame_is_refused_though_the_hash_of_its_index_holds(tmp_path):
    """A flipped byte changes the time, not the size nor the header and chunk index: so a file written
    since is verified whole before its hash is believed."""
    run, split, manifest = _split(tmp_path)
    flip(run, chunk_middle(run, S.FRAMES, 10))
    change = changed_since(run, manifest["runs"][0]["identity"])
    assert change.startswith("frames[10]: checksum mismatch"), change


def test_same_size_and_time_but_other_content_is_refused(tmp_path):
    run, split, manifest = _split(tmp_path)
    recorded = manifest["runs"][0]["identity"]
    data = run.read_bytes()
    run.write_bytes(data.replace(b"sphere10mm", b"sphere15mm"))  # in place: same size
    os.utime(run, ns=(recorded["mtime_ns"], recorded["mtime_ns"]))  # and the time put back
    assert os.stat(run).st_size == recorded["size"] and os.stat(run).st_mtime_ns == recorded["mtime_ns"]
    assert changed_since(run, recorded) == "its header or chunk index differs (same size and time)"
    with pytest.raises(SplitError, match=f"{run}: changed since the split"):
        check_unchanged(manifest, split)
    with open(run, "ab") as fh:
        fh.write(b"\0")
    assert changed_since(run, recorded).startswith(f"its size is {recorded['size'] + 1:,} bytes")


@pytest.mark.parametrize(
    "key,value",
    [("object", "sphere15mm"), ("mm_per_px", 0.25), ("sensor", "rgb_markers"), ("sensor_profile", "")],
)
def test_a_value_edited_in_split_json_is_refused(tmp_path, key, value):
    run, split, manifest = _split(tmp_path)
    manifest["runs"][0][key] = value
    (split / "split.json").write_text(json.dumps(manifest))
    words = rf"split.json: \[runs\]\[0\].{key} is {value!r}, but the run file {run} says"
    with pytest.raises(SplitError, match=words.replace("(", r"\(")):
        TactileDataset(split, "train", size=16)
    args = ["--data", str(split), "--out", str(tmp_path / "m"), "--image-size", "16", "--steps", "1"]
    error = one_error(runner.invoke(train_app, [*args, "--batch-size", "4", "--sample-every", "0"]))
    assert f"[runs][0].{key} is {value!r}" in error and "make the split again" in error, error


@pytest.fixture
def other_profile(tmp_path) -> Path:
    """The shipped profile under another name: another content hash."""
    shipped = Path(default_profile().path)
    folder = tmp_path / "profiles"
    folder.mkdir()
    shutil.copy(shipped.with_suffix(".png"), folder / shipped.with_suffix(".png").name)
    path = folder / "other.toml"
    path.write_text(shipped.read_text().replace('name = "gelsight_mini"', 'name = "other_mini"'))
    return path


def test_train_profile_against_the_recorded_one_is_refused_unless_overridden(tmp_path, other_profile):
    run, split, _ = _split(tmp_path, n=24)
    base = ["--data", str(split), "--image-size", "16", "--steps", "1", "--batch-size", "4", "--sample-every", "0"]
    base += ["--threads", "1", "--conditioning", "physics+plane"]
    error = one_error(runner.invoke(train_app, [*base, "--out", str(tmp_path / "a"), "--profile", str(other_profile)]))
    assert f"{run}: records sensor profile gelsight_mini" in error and "--profile gives other_mini" in error, error
    assert "--override-profile" in error
    given = runner.invoke(
        train_app, [*base, "--out", str(tmp_path / "b"), "--profile", str(other_profile), "--override-profile"]
    )
    assert given.exit_code == 0, given.output
    said = f"{run}: physics conditioning through sensor profile other_mini (sha256 "
    assert said in given.output and "over the run's recorded gelsight_mini" in given.output, given.output
    own = runner.invoke(train_app, [*base, "--out", str(tmp_path / "c")])
    assert own.exit_code == 0, own.output
    assert f"{run}: physics conditioning through sensor profile gelsight_mini (sha256" in own.output
    assert "(recorded in the run)" in own.output, own.output
    same = runner.invoke(train_app, [*base, "--out", str(tmp_path / "d"), "--profile", str(default_profile().path)])
    assert same.exit_code == 0 and "--profile gives the same" in same.output, same.output
