"""The main job continues where it stopped (issue 36): interrupted with Ctrl-C in each of its stages,
`bash scripts/main_job.sh FOLDER` prints the one command that continues it, and that command does:
kept what finished, resumed the interrupted run from the start of its level, resumed training from its
checkpoint, and ended with a report. Small knobs keep it to a few minutes."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import threading
import time
from pathlib import Path

import h5py
import pytest
from realtime_priority import processes

from acquisition import schema as S

ROOT = Path(__file__).resolve().parents[1]
KNOBS = {
    "OBJECTS": "sphere10mm",
    "SPEED_MM_S": "0.5",
    "STEPS": "300",
    "BATCH": "4",
    "EVAL_FRAMES": "4",
    "SETTINGS": "ddim:2",
}
# (the stage's banner, then the line the Ctrl-C waits for, then how long after it, s of real time);
# training is stopped after its checkpoint at step 100, so that the next run resumes from it, and 150
# steps before its end: a loaded machine can read the line seconds after it was printed (at 200 steps,
# with 50 left, training once ended before the Ctrl-C reached it, and nothing was left to resume)
# A Ctrl-C at validate or split was lost (the job ran to its end, training never interrupted) whenever
# the suite had been started in the background by a non-interactive shell, which starts it with SIGINT
# ignored: the job inherited that, and bash cannot trap a signal ignored on entry. The job now starts
# with SIGINT's default action; the failure message says when each Ctrl-C went and who heard it.
STOPS = [
    ("[1/5]", r"^collect|frames", 4.0),
    ("[2/5]", None, 0.2),
    ("[3/5]", None, 0.2),
    ("[4/5]", r"^step 150/300", 0.0),
    ("[5/5]", None, 3.0),
]


def _job(out: Path) -> subprocess.Popen:
    return subprocess.Popen(
        ["bash", "scripts/main_job.sh", str(out)],
        cwd=ROOT,
        env=dict(os.environ, PYTHONUNBUFFERED="1", **KNOBS),  # each line as it is printed
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,  # its own process group: Ctrl-C reaches every process of it, as in a terminal
        # SIGINT's default action, as a terminal's shell gives it: an ignored SIGINT is inherited, and bash
        # cannot trap a signal ignored on entry (a suite started with `&` by a script has it ignored)
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def _signal_state(pgid: int) -> str:
    """Each process of group ``pgid``: its command and whether SIGINT is blocked, ignored or caught."""
    out = []
    for pid, name, _ppid, group in processes():
        if group != pgid:
            continue
        try:
            status = Path(f"/proc/{pid}/status").read_text()
        except OSError:
            continue  # ended meanwhile
        masks = dict(line.split(":\t", 1) for line in status.splitlines() if line.startswith("Sig"))
        sigint = [k for k in ("SigBlk", "SigIgn", "SigCgt") if k in masks and int(masks[k], 16) & 2]
        out.append(f"{pid} {name} SIGINT in {'/'.join(sigint) or 'none (default action)'}")
    return "; ".join(out)


@pytest.fixture
def jobs():
    """Every job started; any still running at the end is killed with its process group, so that a hung one
    fails this test alone (the timeout's signal method below) and leaves nothing running for the next."""
    started: list[subprocess.Popen] = []
    yield started
    for job in started:
        if job.poll() is None:
            os.killpg(job.pid, signal.SIGKILL)
            job.wait()


@pytest.mark.realtime  # Ctrl-C at chosen moments of real time
@pytest.mark.slow
@pytest.mark.timeout(1200, method="signal")
def test_the_main_job_interrupted_in_each_stage_continues_with_one_command(tmp_path, jobs):
    out = tmp_path / "job"
    said, notes = [], []  # notes: when each stop's line was read and whether its Ctrl-C was sent
    for banner, pattern, after_s in STOPS:
        job = _job(out)
        jobs.append(job)
        started = time.monotonic()
        seen = []
        waiting_for = banner
        for line in job.stdout:
            seen.append(line)
            if waiting_for == banner and banner in line:
                if pattern is None:
                    break
                waiting_for = pattern
            elif waiting_for == pattern and re.search(pattern, line):
                break
        read_s, sent, group = time.monotonic() - started, False, ""
        try:
            job.wait(timeout=after_s)
        except subprocess.TimeoutExpired:
            group = _signal_state(job.pid)  # who hears this Ctrl-C, and how (a lost one is being chased)
            os.killpg(job.pid, signal.SIGINT)  # Ctrl-C in the job's terminal
            sent = True
        rest, _ = job.communicate(timeout=300)
        text = "".join(seen) + rest
        said.append(text)
        notes.append(
            f"stop {banner}: its line read {read_s:.1f} s after the job started, Ctrl-C "
            f"{'sent' if sent else 'not sent: the job had ended'}, exit {job.returncode} "
            f"{time.monotonic() - started:.1f} s after the start; the group then: {group}"
        )
        if job.returncode == 0:
            break  # the stage ended before the Ctrl-C reached it: nothing left to continue
        assert job.returncode == 130, text
        assert re.search(rf"interrupted: continue with\n  bash scripts/main_job.sh {re.escape(str(out))}\n", text), text
        assert "Traceback" not in text, text
    final = _job(out)
    jobs.append(final)
    text, _ = final.communicate(timeout=900)
    assert final.returncode == 0, text
    assert (out / "report" / "report.md").is_file()
    assert "continuing" in text and "complete and valid, kept" in text
    run = out / "runs" / "sphere10mm.h5"
    with h5py.File(run, "r") as f:
        assert f[S.STATUS][()] == b"complete"
        assert S.SUPERSEDED in f and (f[S.RETAKE][()] > 0).any()  # interrupted mid-level: that level taken again
    later = said[3:] + [text]  # training went on from its checkpoint:
    threads = ", ".join(t.name for t in threading.enumerate())
    why = "\n".join([*notes, f"threads of the test process: {threads}", *(t[-1500:] for t in [*said, text])])
    assert any("resumed at step" in t for t in later), why
