"""Training on two processes through accelerate (DDP over gloo, CPU): each process reads its own
shard, the loss matches one process at the same global batch, and a checkpoint written by two
processes resumes on one and back (issue 27). Small: 16 px, 32 training frames, a few steps."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from realtime_priority import descendants, process_tree

from tests.test_model_core import make_split_dir

ROOT = Path(__file__).resolve().parents[1]
ACCELERATE = Path(sys.executable).with_name("accelerate")
ARGS = [
    "--preset",
    "tiny",
    "--image-size",
    "16",
    "--conditioning",
    "plane",
    "--batch-size",
    "8",
    "--sample-every",
    "0",
    "--threads",
    "1",
    "--device",
    "cpu",
]


def _run(command: list[str], timeout_s: float = 240) -> str:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}
    env["PYTHONFAULTHANDLER"] = "1"  # a SIGABRT prints every thread's stack: what a hung launch was doing
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        stdout, stderr = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        # hung (seen once in CI, after a resumed two-process run wrote its checkpoint): the launcher and its
        # workers abort, each printing its threads' stacks, which the failure shows
        for pid in reversed(descendants(proc.pid, process_tree())):
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGABRT)
        stdout, stderr = proc.communicate(timeout=60)
        said = f"{stdout[-1500:]}\n{stderr[-8000:]}"
        raise AssertionError(f"hung for {timeout_s:g} s: {' '.join(command[:8])} ...\n{said}") from None
    errors = [line for line in stderr.splitlines() if "rror" in line or "terminate" in line or "what()" in line]
    assert proc.returncode == 0, stdout[-2000:] + "\n".join(errors[:20])
    return stdout


def two_processes(split: Path, out: Path, steps: int, *extra: str) -> str:
    # accelerate 1.15: --multi_gpu starts N processes through torch.distributed.run; with --device cpu
    # they train on the CPU over gloo (--cpu alone starts one process without an MPI hostfile)
    launch = [str(ACCELERATE), "launch", "--multi_gpu", "--num_processes", "2", "--num_machines", "1"]
    launch += ["--mixed_precision", "no", "--dynamo_backend", "no", "--main_process_port", "0"]
    return _run(
        launch
        + ["-m", "cli.model_app", "--data", str(split), "--out", str(out), "--steps", str(steps)]
        + ARGS
        + list(extra)
    )


def one_process(split: Path, out: Path, steps: int, *extra: str) -> str:
    command = [sys.executable, "-m", "cli.model_app", "--data", str(split), "--out", str(out), "--steps", str(steps)]
    return _run(command + ARGS + list(extra))


def state(run: Path) -> dict:
    return json.loads((run / "checkpoint" / "state.json").read_text())


@pytest.mark.skipif(shutil.which(str(ACCELERATE)) is None, reason="accelerate's launcher is not installed")
def test_two_processes_train_their_shards_match_one_and_resume_either_way(tmp_path):
    split = make_split_dir(tmp_path, n=40)  # 32 training frames: 4 steps of 8 are one epoch
    two = two_processes(split, tmp_path / "two", 4)
    assert "x 2 processes" in two
    # each process read its own half of the epoch's items, and nothing else
    for rank in (0, 1):
        assert f"process {rank} of 2: read 16 of 32 training items" in two
    one = one_process(split, tmp_path / "one", 4)
    assert " x 2 processes" not in one
    a, b = np.array(state(tmp_path / "two")["losses"]), np.array(state(tmp_path / "one")["losses"])
    assert len(a) == len(b) == 4
    # the same global batches, the same initial weights; only the second process's noise differs
    assert abs(a.mean() - b.mean()) < 0.15 * b.mean(), (a, b)

    # written by two processes, resumed on one...
    resumed = one_process(split, tmp_path / "two", 6, "--resume")
    assert "resumed at step 4" in resumed and state(tmp_path / "two")["step"] == 6
    # ...and back on two
    back = two_processes(split, tmp_path / "two", 8, "--resume")
    assert "resumed at step 6" in back and "x 2 processes" in back
    final = state(tmp_path / "two")
    assert final["step"] == 8 and len(final["losses"]) == 8 and np.isfinite(final["losses"]).all()


def test_the_processes_shares_of_a_step_are_disjoint_and_make_the_global_batch():
    """The sharding itself, without launching: each share is a disjoint slice of the single-process batch."""
    from types import SimpleNamespace

    from model.training.trainer import TrainConfig, Trainer

    t = Trainer.__new__(Trainer)
    t.config, t.data = TrainConfig(batch_size=8, seed=3), list(range(32))
    t.acc = SimpleNamespace(process_index=0, num_processes=2)
    for step in range(8):
        shares = [set(t.share(step, rank).tolist()) for rank in (0, 1)]
        assert not shares[0] & shares[1] and shares[0] | shares[1] == set(t.batch_indices(step).tolist())
    epoch = [set(np.concatenate([t.share(s, rank) for s in range(4)]).tolist()) for rank in (0, 1)]
    assert len(epoch[0]) == len(epoch[1]) == 16 and not epoch[0] & epoch[1]


@pytest.mark.parametrize("processes", [1, 2])
def test_a_run_on_several_processes_ends_its_process_with_what_it_said_and_frees_nothing(processes):
    """``end_process``: one process returns; several end at once (exit status 0) with their buffered
    output flushed and no destructor run (freeing gloo's process group deadlocked with its worker threads,
    which is why the trainer is kept)."""
    script = (
        "import sys\n"
        "from model.training.train_job import Trained, end_process\n"
        "class Kept:\n"
        "    def __del__(self): print('freed', flush=True)\n"
        f"trained = Trained(None, True, {processes}, kept=Kept())\n"
        "sys.stdout.write('said, not flushed')\n"
        "end_process(trained)\n"
        "print(' and returned')\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert done.returncode == 0, done.stderr
    if processes == 1:
        assert done.stdout.startswith("said, not flushed and returned") and "freed" in done.stdout
    else:
        assert done.stdout == "said, not flushed"


def test_a_failed_process_of_a_run_on_several_processes_says_one_line_and_ends_at_once():
    """With a process group up, a command's error is its one red line, then ``os._exit(1)`` (nothing freed,
    as ``end_process``); a Ctrl-C, its one line and 130. Without one, the usual ``typer.Exit(1)``, and a
    Ctrl-C ends the process by SIGINT."""
    script = (
        "import sys\n"
        "import torch.distributed as dist\n"
        "from cli.model_options import one_line_errors\n"
        "if sys.argv[1] == 'group':\n"
        "    dist.init_process_group('gloo', rank=0, world_size=1, store=dist.HashStore())\n"
        "class Kept:\n"
        "    def __del__(self): print('freed', flush=True)\n"
        "kept = Kept()\n"
        "@one_line_errors\n"
        "def command():\n"
        "    sys.stdout.write('said, not flushed')\n"
        "    raise KeyboardInterrupt if sys.argv[2] == 'ctrl-c' else ValueError('data/split: no such split')\n"
        "try:\n"
        "    command()\n"
        "except BaseException as exc:\n"
        "    print(f' then {type(exc).__name__}')\n"
    )

    def run(*args: str) -> subprocess.CompletedProcess:
        command = [sys.executable, "-c", script, *args]
        return subprocess.run(command, capture_output=True, text=True, cwd=ROOT, timeout=120)

    failed = run("group", "error")
    assert (failed.returncode, failed.stdout) == (1, "said, not flushed"), failed.stderr
    assert failed.stderr.strip() == "error: data/split: no such split"
    stopped = run("group", "ctrl-c")
    assert (stopped.returncode, stopped.stdout, stopped.stderr) == (130, "said, not flushed", "interrupted (Ctrl-C)\n")
    alone = run("alone", "error")
    assert alone.returncode == 0 and alone.stdout.startswith("said, not flushed then Exit") and "freed" in alone.stdout
    # one process, Ctrl-C: the entry point's one line and SIGINT, as an uncaught Ctrl-C ends a program (Typer
    # alone would have ended it with status 130 and nothing said)
    alone_stopped = run("alone", "ctrl-c")
    assert (alone_stopped.returncode, alone_stopped.stderr) == (-signal.SIGINT, "interrupted (Ctrl-C)\n")


def test_the_train_command_ends_a_run_on_several_processes_through_end_process(monkeypatch, tmp_path):
    """``train`` hands what training returned to ``end_process`` (which a two-process run leaves by)."""
    from typer.testing import CliRunner

    import model.training.train_job as job
    from cli.model_app import app

    ended = []
    trained = job.Trained(tmp_path / "checkpoint", True, 2, kept=object())
    monkeypatch.setattr(job, "train", lambda options, log: trained)
    monkeypatch.setattr(job, "end_process", ended.append)
    result = CliRunner().invoke(app, ["--data", str(tmp_path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    assert ended == [trained] and f"checkpoint: {tmp_path / 'checkpoint'}" in result.output
