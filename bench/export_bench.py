"""`dataset export --format lerobot`: time and size of each codec against the run file, and the lossy error.

    .venv/bin/python bench/export_bench.py WORK [--presses DIR] [--codecs lossless,av1,h264] [--quick]

Two runs, each exported with every codec by the command line as a user types it (a fresh process each):

* ``sphere10mm``: `rig run-protocol sphere10mm --sim` (5,783 frames of 256 × 256; ``--quick``: at
  0.1 mm/s, about 720 frames);
* the real GelSight presses (``--presses``: background.png, press_NN.png, presses.csv; 640 × 480 padded to
  640 × 640), made a run by docs/results/real-gelsight/gelsight_folder.py and `dataset import`.

For each: the run file's size, the export's size (video and all), the export's wall time, the import's
wall time back into a run file, and for a lossy codec the mean squared error over every frame against
the run's frames (grey levels², what export reports; max over frames beside it). Prints a markdown table
with the machine named.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common.machine import describe  # noqa: E402

BIN = ROOT / ".venv" / "bin"


def _run(args: list[str]) -> tuple[float, str]:
    start = time.perf_counter()
    done = subprocess.run(args, capture_output=True, text=True)
    took = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"failed ({done.returncode}): {' '.join(args)}\n{done.stdout[-2000:]}{done.stderr[-2000:]}")
    return took, done.stdout


def _size_mb(path: Path) -> float:
    files = [path] if path.is_file() else [p for p in path.rglob("*") if p.is_file()]
    return sum(p.stat().st_size for p in files) / 1e6


def _sphere(work: Path, quick: bool) -> Path:
    out = work / "sphere10mm.h5"
    if not out.exists():
        speed = ["--set", "motion.speed_mm_s=0.1"] if quick else []
        took, _ = _run([str(BIN / "rig"), "run-protocol", "sphere10mm", "--sim", "--out", str(out), *speed])
        print(f"simulated sphere10mm: {took:.0f} s", file=sys.stderr)
    return out


def _presses(work: Path, presses: Path) -> Path:
    out = work / "gelsight.h5"
    if not out.exists():
        folder = work / "gelsight-folder"
        _run(
            [
                str(BIN / "python"),
                str(ROOT / "docs/results/real-gelsight/gelsight_folder.py"),
                str(presses),
                str(folder),
            ]
        )
        _run([str(BIN / "dataset"), "import", str(folder), "--out", str(out), "--sensor", "rgb", "--pad"])
    return out


def _one(run: Path, codec: str, work: Path) -> dict:
    out = work / f"{run.stem}-{codec}"
    back = work / f"{run.stem}-{codec}.back.h5"
    export_s, said = _run(
        [str(BIN / "dataset"), "export", str(run), "--format", "lerobot", "--out", str(out), "--codec", codec]
    )
    import_s, _ = _run([str(BIN / "dataset"), "import", str(out), "--format", "lerobot", "--out", str(back)])
    line = said.strip().splitlines()[-1]
    mse = "0 (bit-exact)"
    if "lossy: MSE" in line:
        mse = line.split("lossy: MSE ")[1].split(";")[0].removesuffix(" against the run's frames")
    frames = int(line.split(": ")[1].split(" frames")[0])
    row = dict(
        run=run.stem,
        codec=codec,
        frames=frames,
        run_mb=_size_mb(run),
        export_mb=_size_mb(out),
        video_mb=_size_mb(out / "videos"),
        export_s=export_s,
        import_s=import_s,
        mse=mse,
    )
    back.unlink()
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("work", type=Path, help="A folder for the runs and exports (kept between calls).")
    parser.add_argument("--presses", type=Path, help="A folder of GelSight presses; without it that row is left out.")
    parser.add_argument("--codecs", default="lossless,av1,h264")
    parser.add_argument("--quick", action="store_true", help="sphere10mm at 0.1 mm/s (about 720 frames).")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    runs = [_sphere(args.work, args.quick)]
    if args.presses is not None and args.presses.is_dir():
        runs.append(_presses(args.work, args.presses))
    elif args.presses is not None:
        print(f"{args.presses}: not found; the real GelSight row is left out", file=sys.stderr)
    rows = [_one(run, codec, args.work) for run in runs for codec in args.codecs.split(",")]
    print(f"machine: {describe()}\n")
    print(
        "| run | frames | codec | run file MB | export MB (video) | export / run file | export s | frames/s | "
        "import s | MSE against the run's frames (max) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['run']} | {r['frames']} | {r['codec']} | {r['run_mb']:.1f} | {r['export_mb']:.2f} "
            f"({r['video_mb']:.2f}) | {r['export_mb'] / r['run_mb']:.2f} | {r['export_s']:.1f} | "
            f"{r['frames'] / r['export_s']:.0f} | {r['import_s']:.1f} | {r['mse']} |"
        )


if __name__ == "__main__":
    main()
