"""A generated corruption corpus × every command that reads run files: refused in one line, or unchanged.

One small, sound run file (33 frames of 32×32, the `quick` protocol's frame count, with a full-rate
stream and the shipped sensor profile) is damaged in each way of ``DAMAGES``: bit flips in the
superblock, in two object headers (the root group's and the frames'), in a middle frame, in the last
frame and in the wrench's row chunk; the file cut by 1000 bytes, to 1000 bytes and to half; and the
content that ``dataset validate`` rejects (a NaN wrench, a duplicate capture_index, phase 99, fewer
frames than rows). Each damaged copy goes through every command of ``COMMANDS`` (validate, info,
split, merge, compact, export, preview, train and evaluate on a split made before the damage, and
``rig run-protocol --resume``), in-process through typer's CliRunner. Each pair must either refuse:
exit 1, no traceback, exactly one ``error:`` line naming the file (and the frame, where the damage is
in one) — or give exactly the undamaged file's output (stdout and written files). A pair that exits
0 with other output is a silent accept; the test fails on any, and on any traceback.

Run with ``-s`` to see the table of outcomes (``CORPUS_TABLE``).
"""

from __future__ import annotations

import hashlib
import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from test_acquisition import QUICK
from test_verified_reads import chunk_index_byte, chunk_middle, flip, write_run
from typer.testing import CliRunner

from acquisition import schema as S
from cli.dataset_app import app as dataset_app
from cli.model_app import app as train_app
from cli.model_app import evaluate_app
from cli.rig_app import app as rig_app
from dataset.split import make_split
from protocols.plan import Plan
from protocols.spec import load_protocol

runner = CliRunner()
MIDDLE = 16


# -- the damages ---------------------------------------------------------------------------


def _header_of(path: Path, name: str | None) -> int:
    with h5py.File(path, "r") as f:
        return h5py.h5o.get_info((f[name] if name else f).id).addr + 12  # inside its OHDR block


def _edit(path: Path, fn) -> None:
    with h5py.File(path, "r+") as f:
        fn(f)


def _cut(path: Path, keep) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: keep(len(data))])


def _relabel(path: Path, old: bytes, new: bytes) -> None:
    """Text attributes live in HDF5's global heap, which has no checksum: edited there, in place."""
    data = path.read_bytes()
    assert old in data and len(old) == len(new)
    path.write_bytes(data.replace(old, new))


def _swap_frames(path: Path, a: int, b: int) -> None:
    """Frames a and b stored in each other's place, each chunk with its own valid checksum."""
    with h5py.File(path, "r+") as f:
        d = f[S.FRAMES]
        origin = (0,) * (d.ndim - 1)
        (mask_a, raw_a), (mask_b, raw_b) = d.id.read_direct_chunk((a, *origin)), d.id.read_direct_chunk((b, *origin))
        d.id.write_direct_chunk((a, *origin), raw_b, mask_b)
        d.id.write_direct_chunk((b, *origin), raw_a, mask_a)


def _zero_page(path: Path, at: int) -> None:
    """The 4 KiB page (as a disk or a filesystem fails) holding byte ``at``, zeroed."""
    data = bytearray(path.read_bytes())
    start = at - at % 4096
    data[start : start + 4096] = bytes(4096)
    path.write_bytes(bytes(data))


def _truncated_under_its_writer(path: Path) -> None:
    """Another process cut the file to 60 % while its writer went on (as before issue 36, when the
    writer noticed nothing): the writer's later writes extend it again, the cut-off part reads zeros."""
    with h5py.File(path, "r+", libver="latest") as f:
        keep = int(path.stat().st_size * 0.6)
        with open(path, "r+b") as other:
            other.truncate(keep)
        f[S.STATUS_REASON][()] = np.bytes_("")  # the writer goes on writing and closes it
        f.flush()


# name: (how to damage a copy, the frame the refusal must name or None)
DAMAGES = {
    "frame chunks swapped": (lambda p: _swap_frames(p, MIDDLE, MIDDLE + 1), MIDDLE),
    "4 KiB page zeroed": (lambda p: _zero_page(p, chunk_middle(p, S.FRAMES, MIDDLE)), None),
    "truncated under its writer": (_truncated_under_its_writer, None),
    "superblock bit flip": (lambda p: flip(p, 13), None),
    "root group header bit flip": (lambda p: flip(p, _header_of(p, None)), None),
    "frames header bit flip": (lambda p: flip(p, _header_of(p, S.FRAMES)), None),
    "middle frame bit flip": (lambda p: flip(p, chunk_middle(p, S.FRAMES, MIDDLE)), MIDDLE),
    "last frame bit flip": (lambda p: flip(p, chunk_middle(p, S.FRAMES, -1)), "last"),
    "wrench chunk bit flip": (lambda p: flip(p, chunk_middle(p, S.WRENCH, 0)), None),
    "stream chunk bit flip": (lambda p: flip(p, chunk_middle(p, S.WRENCH_STREAM, 0)), None),
    "object image bit flip": (lambda p: flip(p, chunk_middle(p, S.OBJECT_IMAGE, 0)), None),
    "reference frame bit flip": (lambda p: flip(p, chunk_middle(p, S.REFERENCE_FRAME, 0)), None),
    "frames chunk index bit flip": (lambda p: flip(p, chunk_index_byte(p, S.FRAMES)), None),
    "object name relabelled": (lambda p: _relabel(p, b"sphere10mm", b"sphere15mm"), None),
    "cut by 1000 bytes": (lambda p: _cut(p, lambda n: n - 1000), None),
    "cut to 1000 bytes": (lambda p: _cut(p, lambda n: 1000), None),
    "cut to half": (lambda p: _cut(p, lambda n: n // 2), None),
    "NaN wrench": (lambda p: _edit(p, lambda f: f[S.WRENCH].__setitem__((5, 2), np.nan)), 5),
    "duplicate capture_index": (lambda p: _edit(p, lambda f: f[S.CAPTURE_INDEX].__setitem__(10, 9)), 10),
    "phase 99": (lambda p: _edit(p, lambda f: f[S.PHASE_INDEX].__setitem__(7, 99)), 7),
    "fewer frames than rows": (
        lambda p: _edit(p, lambda f: f[S.FRAMES].resize(f[S.FRAMES].shape[0] - 1, axis=0)),
        None,
    ),
}


# -- the commands: (app, arguments) for a run file in a case folder -------------------------


def _commands(corpus: dict) -> dict:
    quick, good2, model = corpus["protocol"], corpus["good2"], corpus["model"]
    return {
        "validate": lambda run, d: (dataset_app, ["validate", str(run)]),
        "info": lambda run, d: (dataset_app, ["info", str(run)]),
        "split": lambda run, d: (dataset_app, ["split", "8:2", str(run), "--out", str(d / "split-after")]),
        "merge": lambda run, d: (dataset_app, ["merge", str(run), str(good2), "--out", str(d / "merged.h5")]),
        "compact": lambda run, d: (dataset_app, ["compact", str(run)]),
        "export": lambda run, d: (dataset_app, ["export", str(run), "--out", str(d / "exported")]),
        "preview": lambda run, d: (dataset_app, ["preview", str(run), "--out", str(d / "sheet.png"), "--tiles", "4"]),
        "train": lambda run, d: (
            train_app,
            ["--data", str(d / "split"), "--out", str(d / "trained"), "--image-size", "16", "--steps", "1"]
            + ["--batch-size", "4", "--sample-every", "0", "--conditioning", "plane+embedding", "--threads", "1"],
        ),
        "evaluate": lambda run, d: (
            evaluate_app,
            ["--checkpoint", str(model), "--split", str(d / "split"), "--out", str(d / "report")]
            + ["--settings", "ddim:1", "--limit", "2", "--no-force-sweep", "--threads", "1"],
        ),
        "resume": lambda run, d: (rig_app, ["run-protocol", str(quick), "--sim", "--resume", str(run)]),
    }


COMMAND_NAMES = ("validate", "info", "split", "merge", "compact", "export", "preview", "train", "evaluate", "resume")
WRITTEN = ("split-after", "merged.h5", "exported", "sheet.png", "report")  # what a command may write in its folder


def _case(root: Path, name: str, good: Path, damage=None) -> Path:
    """A folder with the run (damaged by ``damage``) and a split of it made before the damage."""
    folder = root / re.sub(r"\W+", "-", name)
    folder.mkdir()
    run = folder / "run.h5"
    shutil.copy(good, run)
    make_split([run], "8:2", folder / "split")
    if damage is not None:
        damage(run)
    return folder


def _written(folder: Path) -> dict[str, str]:
    """{relative path: sha256} of what a command wrote (the report's timings excluded: they vary)."""
    out = {}
    for name in WRITTEN:
        base = folder / name
        paths = [base] if base.is_file() else sorted(p for p in base.rglob("*") if p.is_file()) if base.exists() else []
        for p in paths:
            if p.suffix in (".h5",):
                continue  # HDF5 files carry their creation time: compared by validate instead
            if p.name in ("report.md", "metrics.json", "error_vs_time.png"):
                continue
            out[str(p.relative_to(folder))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def _run(command, run: Path, folder: Path):
    app, args = command(run, folder)
    result = runner.invoke(app, args)
    text = result.output.replace(str(folder), "<case>")
    text = re.sub(r"\(1/1 files, [^)]*\)", "(1/1 files)", text)  # validate's elapsed time
    return result, text


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    root = tmp_path_factory.mktemp("corpus")
    (root / "quick.toml").write_text(QUICK)
    protocol = load_protocol(root / "quick.toml")
    n = Plan.of(protocol).frame_count
    good = write_run(root / "good.h5", n, seed=0, protocol=protocol)
    good2 = write_run(root / "good2.h5", n, seed=1, protocol=protocol)
    # a tiny model trained once on a sound split, for evaluate
    base = _case(root, "model", good)
    trained = runner.invoke(
        train_app,
        ["--data", str(base / "split"), "--out", str(base / "model"), "--image-size", "16", "--steps", "2"]
        + ["--batch-size", "4", "--sample-every", "0", "--conditioning", "plane+embedding", "--threads", "1"],
    )
    assert trained.exit_code == 0, trained.output
    corpus = {"root": root, "good": good, "good2": good2, "protocol": root / "quick.toml", "model": base / "model"}
    corpus["commands"] = _commands(corpus)
    corpus["baseline"] = {}
    for name in COMMAND_NAMES:  # each command on the sound file: what an unchanged output is
        folder = _case(root, f"sound-{name}", good)
        result, text = _run(corpus["commands"][name], folder / "run.h5", folder)
        assert result.exit_code == 0, (name, result.output)
        corpus["baseline"][name] = (text, _written(folder))
    return corpus


CORPUS_TABLE: dict[tuple[str, str], str] = {}


@pytest.mark.parametrize("damage", list(DAMAGES))
def test_every_command_refuses_the_damage_in_one_line_or_is_unchanged(corpus, damage):
    fn, frame = DAMAGES[damage]
    outcomes = {}
    for name in COMMAND_NAMES:
        folder = _case(corpus["root"], f"{damage}-{name}", corpus["good"], fn)
        run = folder / "run.h5"
        result, text = _run(corpus["commands"][name], run, folder)
        assert "Traceback" not in result.output, (damage, name, result.output)
        assert result.exception is None or isinstance(result.exception, SystemExit), (damage, name, result.exception)
        if result.exit_code == 0:
            same = (text, _written(folder)) == corpus["baseline"][name]
            assert same, f"silent accept: {name} on {damage} exits 0 with other output:\n{result.output}"
            outcomes[name] = "identical"
            continue
        assert result.exit_code == 1, (damage, name, result.output)
        if name == "validate":  # validate lists its findings, one line each, naming the file
            findings = [line for line in result.output.splitlines() if line.startswith(f"  {run}: ")]
            assert findings and f"{run}: {len(findings)} finding(s)" in result.output, result.output
            named = "\n".join(findings)
        else:
            errors = [line for line in result.output.splitlines() if line.startswith("error:")]
            assert len(errors) == 1, (damage, name, result.output)
            named = errors[0]
        assert str(run) in named, (damage, name, named)
        if frame is not None and name not in ("train", "evaluate"):  # those refuse the changed file before any frame
            index = 32 if frame == "last" else frame
            assert re.search(rf"frames?\[?\s?{index}\b|frame {index}\b|\[{index}\]", named), (damage, name, named)
        outcomes[name] = "refused"
    for name, outcome in outcomes.items():
        CORPUS_TABLE[(damage, name)] = outcome
    # what must refuse whatever the damage: every command that reads the whole file or trusts a split
    # (compact of a file compressed already reads no frame: its output stays the sound file's)
    for name in ("validate", "split", "merge", "export", "train", "evaluate", "resume"):
        assert outcomes[name] == "refused", (damage, name)


def test_zz_print_the_table():
    """The outcome table (run with -s to see it): damage × command → refused / identical."""
    if not CORPUS_TABLE:
        pytest.skip("the corpus did not run in this session")
    print("\n| damage | " + " | ".join(COMMAND_NAMES) + " |")
    print("|---|" + "---|" * len(COMMAND_NAMES))
    for damage in DAMAGES:
        print(f"| {damage} | " + " | ".join(CORPUS_TABLE.get((damage, c), "?") for c in COMMAND_NAMES) + " |")
    silent = [k for k, v in CORPUS_TABLE.items() if v not in ("refused", "identical")]
    assert not silent


# -- --resume of a run whose writer crashed (status running) ----------------------------------


def _grow_stream(path: Path, rows: int) -> None:
    """The stream's extent grown by ``rows`` that were never written, as a kill between the two leaves it."""
    _edit(path, lambda f: f[S.WRENCH_STREAM].resize(f[S.WRENCH_STREAM].shape[0] + rows, axis=0))


# name: (how the crash or damage left the file, the frame or stream rows the refusal names; None: resumed)
CRASHES = {
    "sound": (lambda p: None, None),
    "last frame cut short": (lambda p: flip(p, chunk_middle(p, S.FRAMES, -1)), None),
    "stream tail never written": (lambda p: _grow_stream(p, 5), None),
    "middle frame damaged": (lambda p: flip(p, chunk_middle(p, S.FRAMES, 8)), "frames[8]"),
    "stream chunk damaged before a sound one": (
        lambda p: flip(p, chunk_middle(p, S.WRENCH_STREAM, 0)),
        "wrench_stream[0:1024]",
    ),
}


@pytest.mark.parametrize("crash", list(CRASHES))
def test_resume_of_a_crashed_run_keeps_what_reached_the_disk_and_refuses_damage(tmp_path, crash):
    """A run killed after 20 of its 33 frames (status running; 60 stream rows a frame, so two stream
    chunks): `--resume` drops only a tail that never reached the disk and completes the run, which
    then validates; damage followed by sound frames or stream rows is refused in one line naming them."""
    from dataset.runs import validate

    (tmp_path / "quick.toml").write_text(QUICK)
    protocol = load_protocol(tmp_path / "quick.toml")
    n = Plan.of(protocol).frame_count
    run = write_run(tmp_path / "crashed.h5", n, written=20, close=False, protocol=protocol, samples=60, size=256)
    damage, named = CRASHES[crash]
    damage(run)
    result = runner.invoke(rig_app, ["run-protocol", str(tmp_path / "quick.toml"), "--sim", "--resume", str(run)])
    assert "Traceback" not in result.output, result.output
    if named is None:
        assert result.exit_code == 0, result.output
        assert validate(run) == [], validate(run)
        with h5py.File(run, "r") as f:
            assert f[S.FRAMES].shape[0] == n and f[S.STATUS][()] == b"complete"
        return
    assert result.exit_code == 1, result.output
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and str(run) in errors[0] and named in errors[0] and "cannot resume" in errors[0], errors
    assert not list(tmp_path.glob("*.lock"))
