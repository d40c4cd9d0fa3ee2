"""Issue 17's pieces: elapsed/time-left arithmetic (common/eta.py), the torch thread rule
(model/denoiser/threads.py), the training progress line with its time left, the trainer's item cache."""

from __future__ import annotations

import subprocess
import sys

import pytest

from common.eta import Eta, format_duration, main, staged_left, time_left
from model.denoiser.threads import choose_threads, decide, parse_override, running_now


class FakeClock:
    def __init__(self, t: float = 100.0):
        self.t = t

    def __call__(self) -> float:
        return self.t


@pytest.mark.parametrize(
    "seconds, text",
    [
        (0, "0 s"),
        (7.4, "7 s"),
        (59.6, "1 min 00 s"),
        (65, "1 min 05 s"),
        (3599, "59 min 59 s"),
        (3600 + 180, "1 h 03 min"),
        (-1, "?"),
        (float("nan"), "?"),
        (float("inf"), "?"),
    ],
)
def test_durations_read_as_minutes_and_seconds(seconds, text):
    assert format_duration(seconds) == text


def test_time_left_extrapolates_the_rate_so_far():
    assert time_left(25, 100, 10.0) == pytest.approx(30.0)
    assert time_left(100, 100, 10.0) == 0.0
    assert time_left(0, 100, 10.0) is None  # nothing done: no rate yet
    assert time_left(10, 100, float("nan")) is None
    assert time_left(10, 0, 1.0) is None


def test_eta_lines_on_an_injected_clock():
    clock = FakeClock()
    eta = Eta(200, clock)
    assert eta.line(0) == "0 s"
    clock.t += 30
    assert eta.line(50) == "30 s, about 1 min 30 s left"
    clock.t += 90
    assert eta.line(200) == "2 min 00 s"  # the end: no time left shown
    # a resumed run: the rate counts only the steps taken since it started
    eta.start(first=100)
    clock.t += 10
    assert eta.left(150) == pytest.approx(10.0)


def test_a_staged_job_scales_the_rest_by_the_pace_so_far():
    expected = [30, 1, 1, 90, 40]
    assert staged_left(expected, 0, 0.0) == pytest.approx(162)
    # the first stage took twice its expected time: the rest is expected to as well
    assert staged_left(expected, 1, 60.0) == pytest.approx(2 * 132)
    # one odd stage cannot swing it beyond x10 or below x0.5
    assert staged_left(expected, 1, 3000.0) == pytest.approx(10 * 132)
    assert staged_left(expected, 1, 1.0) == pytest.approx(0.5 * 132)
    assert staged_left(expected, 5, 200.0) == 0.0
    with pytest.raises(ValueError, match="finished stages 6"):
        staged_left(expected, 6, 1.0)
    with pytest.raises(ValueError, match="finite"):
        staged_left([1, float("nan")], 0, 1.0)


def test_the_job_script_helper_prints_one_line_and_refuses_bad_numbers(capsys):
    assert main(["30,1,90", "1", "60"]) == 0
    assert capsys.readouterr().out.strip() == "about 3 min 02 s left"
    for argv in (["30,x", "1", "2"], ["30,1", "1", "nan"], ["30,1", "1", "-5"], ["30,1", "3", "5"], ["30"]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("common.eta: ") and "\n" not in err
    # as the script runs it
    done = subprocess.run(
        [sys.executable, "-m", "common.eta", "10,10", "1", "5"], capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == "about 5 s left"


def test_threads_one_per_free_core():
    assert choose_threads(2, 1.0) == 2  # only this process runs: both cores
    assert choose_threads(2, 2.0) == 1  # one other process keeps a core busy
    assert choose_threads(2, 7.0) == 1  # never fewer than one
    assert choose_threads(16, 4.0) == 13
    assert choose_threads(2, 1.4) == 2 and choose_threads(2, 1.6) == 1  # sampled means round
    assert choose_threads(4, None) == 4  # unknown load: all cores


def test_running_now_reads_proc_stat_and_averages_samples():
    reads = iter(["cpu 1 2\nprocs_running 3\n", "procs_running 1\n"])
    waits: list[float] = []
    assert running_now(samples=2, read=lambda: next(reads), wait=waits.append) == pytest.approx(2.0)
    assert waits == [0.02]  # the samples are spread in time, on the injected clock
    assert running_now(samples=1, read=lambda: "cpu 1 2\n") is None

    def broken() -> str:
        raise OSError("no /proc")

    assert running_now(read=broken, wait=lambda s: None) is None


def test_thread_overrides_are_checked_and_win():
    assert decide(3, env={}, running=9.0) == (3, "--threads")
    assert decide(None, env={"TACTILE_TORCH_THREADS": "2"}, running=9.0) == (2, "TACTILE_TORCH_THREADS")
    n, why = decide(None, env={}, running=1.0)
    assert n >= 1 and "core" in why
    assert decide(None, env={"TACTILE_TORCH_THREADS": ""}, running=1.0)[1] != "TACTILE_TORCH_THREADS"
    for bad in ("0", "-1", "two", "1.5", "nan", "100000"):
        with pytest.raises(ValueError, match="TACTILE_TORCH_THREADS: expected a whole number of threads 1–256"):
            decide(None, env={"TACTILE_TORCH_THREADS": bad})
    with pytest.raises(ValueError, match="--threads"):
        parse_override(0, "--threads")


def test_the_progress_line_shows_rate_elapsed_and_time_left():
    import torch

    from model.training.callbacks import Progress
    from model.training.trainer import TrainConfig, Trainer
    from tests.test_trainer import LinearLoss, toy_data

    clock, lines = FakeClock(), list[str]()

    class Tick(Progress):  # each step takes 2 s on the fake clock
        def on_step_end(self, trainer):
            clock.t += 2.0
            super().on_step_end(trainer)

    torch.manual_seed(0)
    cfg = TrainConfig(steps=8, batch_size=4, seed=0)
    trainer = Trainer(cfg, torch.nn.Linear(3, 1), LinearLoss(), toy_data(), [Tick(lines.append, every=2, clock=clock)])
    trainer.train(until=4)
    assert lines[0].startswith("step 2/4  loss ")
    assert lines[0].endswith("2.0 images/s  4 s, about 4 s left")  # 2 steps x 4 images in 4 s
    assert lines[1].endswith("2.0 images/s  8 s")  # the last step: no time left shown
    trainer.train()  # on to step 8: a second call times itself afresh
    assert lines[2].startswith("step 6/8") and lines[2].endswith("4 s, about 4 s left")


def test_the_trainer_reads_each_item_once_and_trains_the_same():
    import torch

    from model.training.trainer import TrainConfig, Trainer
    from tests.test_trainer import LinearLoss, toy_data

    class Counting(list):
        reads = 0

        def __getitem__(self, i):
            Counting.reads += 1
            return super().__getitem__(i)

    data = Counting(toy_data())
    torch.manual_seed(0)
    cached = Trainer(TrainConfig(steps=9, batch_size=4, seed=2), torch.nn.Linear(3, 1), LinearLoss(), data)
    losses = cached.train()
    assert Counting.reads == len(data)  # 9 steps of 4 from 12 items: each read once

    import model.training.trainer as T

    torch.manual_seed(0)
    old, T.ITEM_CACHE_BYTES = T.ITEM_CACHE_BYTES, 0  # nothing kept: every step reads its items
    try:
        plain = Trainer(TrainConfig(steps=9, batch_size=4, seed=2), torch.nn.Linear(3, 1), LinearLoss(), toy_data())
        assert plain.train() == losses
        assert not plain._items
    finally:
        T.ITEM_CACHE_BYTES = old
