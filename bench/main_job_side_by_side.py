"""The main job as a user types it (`bash scripts/main_job.sh`), from two trees in turn.

    .venv/bin/python bench/first_result_bench.py --main-job-vs OLD_TREE [--rounds 2] [--work DIR]

OLD_TREE is another checkout (e.g. `git worktree add /tmp/old main`); both run with this
checkout's `.venv` and `PYTHONPATH` set to their own tree, so each runs its own code. The runs
alternate (this, old, old, this, …) so that a drift in the machine's load falls on both alike.
Each row: the job's wall time and stage times as the job itself prints them, its peak memory, and
the report's DDIM line (MSE, MAE, SSIM, PSNR with their 95 % intervals) from `report/report.md`.
"""

from __future__ import annotations

import os
import re
import subprocess
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent
STAGES = re.compile(r"^stages: (.*); load average ([\d. ]+) at the start, ([\d. ]+) at the end", re.M)
DDIM_ROW = re.compile(r"^\| this model \(ddim, (\d+) steps\) \| ([^|]+) \| ([^|]+) \| ([^|]+) \| ([^|]+) \|", re.M)


def run_job(tree: Path, out: Path) -> dict:
    """One main job of ``tree`` into ``out``: its wall time, stages, peak memory and report row."""
    log = out.parent / f"{out.name}.log"
    start = time.perf_counter()
    with open(log, "w") as sink:
        proc = subprocess.Popen(
            ["bash", str(tree / "scripts" / "main_job.sh"), str(out)],
            cwd=tree,
            env=dict(os.environ, PYTHONPATH=str(tree)),
            stdout=sink,
            stderr=subprocess.STDOUT,
        )
        # wait4: this job's own rusage, whose ru_maxrss (KiB) is the largest process of its tree; the
        # process-wide RUSAGE_CHILDREN would carry an earlier, larger job's peak into later rows
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
    wall_s = time.perf_counter() - start
    output = log.read_text()
    if proc.returncode != 0:
        raise SystemExit(f"{tree}: the main job failed (exit {proc.returncode}): {output.strip()[-400:]} ({log})")
    stages = STAGES.search(output)
    report = (out / "report" / "report.md").read_text()
    ddim = DDIM_ROW.search(report)
    if stages is None or ddim is None:
        raise SystemExit(f"{tree}: no stage line or DDIM row in the job's output ({log})")
    return {
        "wall_s": wall_s,
        "peak_MB": usage.ru_maxrss / 1024,
        "stages": stages.group(1),
        "load": f"{stages.group(2).split()[0]} → {stages.group(3).split()[0]}",
        "ddim": f"{ddim.group(1)} steps: MSE {ddim.group(2).strip()}, MAE {ddim.group(3).strip()}, "
        f"SSIM {ddim.group(4).strip()}, PSNR {ddim.group(5).strip()}",
    }


def side_by_side(old_tree: Path, work: Path, rounds: int) -> None:
    from common.machine import describe

    old_tree = old_tree.resolve()
    if not (old_tree / "scripts" / "main_job.sh").is_file():
        raise SystemExit(f"{old_tree}: no scripts/main_job.sh: expected another checkout of this project")
    work.mkdir(parents=True, exist_ok=True)
    order = []
    for r in range(rounds):  # this, old, old, this, this, old, …
        pair = [("this", HERE), ("old", old_tree)]
        order += pair if r % 2 == 0 else pair[::-1]
    print(f"machine: {describe()}; load average at the start {os.getloadavg()[0]:.1f}")
    print(f"this: {HERE}\nold:  {old_tree}\n")
    print("| tree | round | total | stages | load average (start → end) | peak memory | report (DDIM) |")
    print("|---|---|---|---|---|---|---|")
    totals: dict[str, list[float]] = {"this": [], "old": []}
    for k, (name, tree) in enumerate(order):
        row = run_job(tree, work / f"{name}-{k}")
        totals[name].append(row["wall_s"])
        m, s = divmod(round(row["wall_s"]), 60)
        print(
            f"| {name} | {k + 1} | **{m} min {s:02d} s** | {row['stages']} | {row['load']} | "
            f"{row['peak_MB']:.0f} MB | {row['ddim']} |",
            flush=True,
        )
    mean = {k: sum(v) / len(v) for k, v in totals.items()}
    print(f"\nmean: this {mean['this']:.0f} s, old {mean['old']:.0f} s; this / old = {mean['this'] / mean['old']:.2f}")
