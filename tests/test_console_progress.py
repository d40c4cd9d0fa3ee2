"""The progress sidecar of `rig run-protocol` (cli/console/run_progress.py) and the console's
reading of it, without a browser: throttling on an injected clock, whole-file writes, every
value of a sidecar checked, and a run file's latest pair read while it is being written."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from acquisition.executor import Progress
from cli.console.run_progress import (
    STALE_AFTER_S,
    BadProgress,
    ProgressWriter,
    read_progress,
    sidecar_path,
)


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def progress(frame: int, phase: str = "press", level: int = 1, frames: int = 40) -> Progress:
    return Progress(frame, frames, phase, level, float(frame), 40.0, np.arange(6.0) * 0.5, 0.0)


def test_writes_are_throttled_and_whole(tmp_path):
    run = tmp_path / "r.h5"
    clock, wall = Clock(), Clock()
    writer = ProgressWriter(run, protocol="p", frames=40, levels_mm=[0.4, 0.8], now=clock, wall=wall, every_s=0.5)
    writer.update(progress(1))
    assert writer.writes == 1  # the first is always written
    first = read_progress(sidecar_path(run), wall)
    assert (first["frame"], first["phase"], first["level"], first["depth_mm"]) == (1, "press", 1, 0.4)
    assert first["wrench"] == [0.0, 0.5, 1.0, 1.5, 2.0, 2.5] and not first["stale"]
    clock.t += 0.1
    writer.update(progress(2))
    assert writer.writes == 1 and read_progress(sidecar_path(run), wall)["frame"] == 1  # too soon
    clock.t += 0.1
    writer.update(progress(3, phase="shear"))  # a new phase is written at once
    assert writer.writes == 2
    clock.t += 0.5
    writer.update(progress(5, phase="shear"))  # 4 frames in 0.7 s: 35 left take 35 × 0.175 s
    state = read_progress(sidecar_path(run), wall)
    assert state["frame"] == 5 and state["eta_s"] == pytest.approx(0.7 / 4 * 35)
    writer.update(progress(40, phase="return", level=2))  # the last frame is always written
    assert read_progress(sidecar_path(run), wall)["depth_mm"] == 0.8
    assert not list(tmp_path.glob(".*tmp"))  # no temporary file left behind
    writer.close()
    assert not sidecar_path(run).exists()


def test_a_silent_writer_reads_as_stale(tmp_path):
    run = tmp_path / "r.h5"
    wall = Clock()
    ProgressWriter(run, protocol="p", frames=40, levels_mm=[0.4], wall=wall).update(progress(1))
    wall.t += STALE_AFTER_S + 1
    state = read_progress(sidecar_path(run), wall)
    assert state["stale"] and state["age_s"] == pytest.approx(STALE_AFTER_S + 1)


def test_an_unwritable_folder_never_stops_the_run(tmp_path):
    writer = ProgressWriter(tmp_path / "gone" / "r.h5", protocol="p", frames=40, levels_mm=[0.4])
    writer.update(progress(1))  # no exception: the run goes on, the failure is counted
    assert writer.failures == 1 and writer.writes == 0


@pytest.mark.parametrize(
    ("key", "value", "expected"),
    [
        ("frame", -1, "frame = -1, expected a whole number in 0..40"),
        ("frame", 41, "frame = 41, expected a whole number in 0..40"),
        ("frame", 2.5, "frame = 2.5"),
        ("eta_s", math.nan, "eta_s = nan, expected a number"),
        ("eta_s", -3.0, "eta_s = -3.0"),
        ("frames", 0, "frames = 0"),
        ("level", True, "level = True"),
        ("wrench", [1, 2, 3], "wrench = [1, 2, 3], expected 6 numbers"),
        ("wrench", [1, 2, 3, 4, 5, math.inf], "wrench = inf"),
        ("phase", 7, "phase = 7, expected a short text"),
        ("version", 99, "version 99, expected 1"),
    ],
)
def test_every_value_of_a_sidecar_is_checked(tmp_path, key, value, expected):
    run = tmp_path / "r.h5"
    ProgressWriter(run, protocol="p", frames=40, levels_mm=[0.4]).update(progress(3))
    side = sidecar_path(run)
    record = json.loads(side.read_text())
    record[key] = value
    side.write_text(json.dumps(record))  # json writes NaN and Infinity, as a careless tool would
    with pytest.raises(BadProgress) as bad:
        read_progress(side)
    message = str(bad.value)
    assert message.startswith("r.h5.progress.json: ") and expected in message and "\n" not in message


def test_not_json_is_one_line(tmp_path):
    side = tmp_path / "r.h5.progress.json"
    side.write_text("{half")
    with pytest.raises(BadProgress, match=r"^r\.h5\.progress\.json: not readable as JSON"):
        read_progress(side)


def test_the_console_lists_runs_in_progress_then_how_they_ended(tmp_path):
    from cli.console.runs import FINISHED_SHOWN_S, ProgressWatch, RunLibrary

    run = tmp_path / "r.h5"
    run.write_bytes(b"not hdf5")  # the file's side fails alone, named; the sidecar's side still shows
    (tmp_path / "other.h5").write_bytes(b"")  # no sidecar, never seen running: not listed
    wall = Clock()
    writer = ProgressWriter(run, protocol="p", frames=40, levels_mm=[0.4], wall=wall)
    writer.update(progress(7, phase="shear"))
    watch = ProgressWatch(RunLibrary(folders=[tmp_path]))
    (entry,) = watch.poll(wall.t)
    assert (entry["run"], entry["phase"], entry["frame"], entry["finished"]) == ("r.h5", "shear", 7, False)
    assert entry["file_error"].startswith("r.h5: ")
    writer.close()
    (ended,) = watch.poll(wall.t + 1)
    assert ended["run"] == "r.h5" and ended["finished"] and "phase" not in ended
    assert watch.poll(wall.t + FINISHED_SHOWN_S + 1) == []
    sidecar_path(run).write_text('{"version": 1, "frame": "many"}')
    (bad,) = watch.poll(wall.t)
    assert bad["run"] == "r.h5" and bad["error"].startswith("r.h5.progress.json: ")
