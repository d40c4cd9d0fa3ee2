"""Reading a LeRobot dataset folder with the ecosystem's own code, offline, for tests to compare with the source.

read_with_lerobot(folder, tmp_path): LeRobotDataset (the standalone lerobot-dataset package, import path
ledataset) in a process of its own (tests/lerobot_reader/read.py), every item's values stacked over the dataset.
load_with_hf_datasets(folder, tmp_path): the data parquet files through Hugging Face `datasets`, as the Hub's
viewer and `load_dataset` see them. write_with_lerobot(folder, tmp_path, arrays): a folder written by LeRobot's
own writer (tests/lerobot_reader/write.py), the reference for what the ecosystem makes. lerobot_available():
None when the reader is installed and can decode video, else why not; outside CI a test skips with that reason,
in CI (CI=true) it fails (require_lerobot()).

The reader's process gets (reader_env()):
- PYTHONPATH=tests/lerobot_reader first: its torchvision is a stub (PyPI's torchvision does not import against
  the project's torch), the reader needing only ToTensor, a few transforms.v2 names and, for the "pyav" video
  backend, io.VideoReader (done there with PyAV);
- HF_HUB_OFFLINE=1, HF_DATASETS_OFFLINE=1, HF_HOME and HF_DATASETS_CACHE under tmp_path: nothing from the Hub,
  nothing cached outside the test;
- LD_LIBRARY_PATH=<links>:<site-packages>/av.libs: torchcodec loads FFmpeg's shared libraries by their plain
  sonames (libavutil.so.60, ...), which no system library provides here; PyAV's wheel bundles them under hashed
  names (libavutil-5809ad29.so.60...), so <links> holds libavutil.so.60 -> that file, and so on for avcodec,
  avformat, avdevice, avfilter, swscale and swresample. The loader reads LD_LIBRARY_PATH when a process starts,
  hence a process of its own.
"""

from __future__ import annotations

import functools
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

READER_DIR = Path(__file__).resolve().parent / "lerobot_reader"
READ_SCRIPT = READER_DIR / "read.py"
WRITE_SCRIPT = READER_DIR / "write.py"
FFMPEG_LIBS = ("avutil", "avcodec", "avformat", "avdevice", "avfilter", "swscale", "swresample")
READ_TIMEOUT_S = 120


def _av_libs() -> Path | None:
    spec = importlib.util.find_spec("av")
    if spec is None or not spec.submodule_search_locations:
        return None
    libs = Path(next(iter(spec.submodule_search_locations))).parent / "av.libs"
    return libs if libs.is_dir() else None


def ffmpeg_links(into: Path) -> Path:
    """A folder of FFmpeg's sonames (libavutil.so.60 -> PyAV's bundled libavutil-<hash>.so.60.x.y), made once."""
    libs = _av_libs()
    if libs is None:
        raise RuntimeError("PyAV's bundled FFmpeg (site-packages/av.libs) is not there: install av (pyproject.toml)")
    into.mkdir(parents=True, exist_ok=True)
    for name in FFMPEG_LIBS:
        found = sorted(libs.glob(f"lib{name}-*.so.*"))
        if not found:
            raise RuntimeError(f"no lib{name} in {libs}: torchcodec cannot load FFmpeg")
        major = re.match(rf"lib{name}-[^.]+\.so\.(\d+)", found[-1].name)
        if major is None:
            raise RuntimeError(f"cannot tell the soname of {found[-1]}")
        link = into / f"lib{name}.so.{major.group(1)}"
        try:
            link.symlink_to(found[-1])
        except FileExistsError:  # made by an earlier call
            pass
    return into


def reader_env(tmp_path: Path, video_backend: str = "torchcodec") -> dict[str, str]:
    """The environment of the reader's process (see the module's text)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(READER_DIR), *filter(None, [env.get("PYTHONPATH")])])
    env.update(
        HF_HUB_OFFLINE="1",
        HF_DATASETS_OFFLINE="1",
        HF_HOME=str(tmp_path / "hf-home"),
        HF_DATASETS_CACHE=str(tmp_path / "hf-datasets-cache"),
        HF_HUB_DISABLE_TELEMETRY="1",
        TQDM_DISABLE="1",
        PYTHONWARNINGS="ignore",
    )
    if video_backend == "torchcodec":
        links = ffmpeg_links(tmp_path / "ffmpeg-sonames")
        env["LD_LIBRARY_PATH"] = os.pathsep.join(
            [str(links), str(_av_libs()), *filter(None, [env.get("LD_LIBRARY_PATH")])]
        )
    return env


def _load(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {key: z[key] for key in z.files}


def read_with_lerobot(folder: Path, tmp_path: Path, video_backend: str = "torchcodec") -> dict[str, np.ndarray]:
    """Every item of LeRobotDataset(root=folder), stacked per key (see tests/lerobot_reader/read.py); camera keys
    as uint8 (N, H, W, C). Raises AssertionError with the reader's own error when it cannot read the folder."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    out = Path(tempfile.mkstemp(suffix=".npz", prefix="lerobot-read-", dir=tmp_path)[1])
    cmd = [sys.executable, str(READ_SCRIPT), str(folder), str(out), "--video-backend", video_backend]
    done = subprocess.run(
        cmd, env=reader_env(tmp_path, video_backend), capture_output=True, text=True, timeout=READ_TIMEOUT_S
    )
    if done.returncode != 0:
        raise AssertionError(f"LeRobot's reader failed on {folder} (exit {done.returncode}):\n{done.stderr[-6000:]}")
    return _load(out)


# LeRobot's writer encodes with SVT-AV1, which switches its process to real-time priority (SCHED_FIFO 99) where
# it may (as root): for the seconds it encodes it would hold the cores ahead of the realtime tests' devices
# (common/scheduling.py does it for this project's own export). Without CAP_SYS_NICE it may not, and says so.
_SETPRIV = ["setpriv", "--inh-caps=-sys_nice", "--bounding-set=-sys_nice"]


@functools.cache
def _no_real_time() -> list[str]:
    """The prefix that starts a command without CAP_SYS_NICE, where setpriv can drop it (it needs CAP_SETPCAP)."""
    if os.geteuid() != 0 or not shutil.which("setpriv"):
        return []
    works = subprocess.run([*_SETPRIV, "true"], capture_output=True, timeout=30).returncode == 0
    return _SETPRIV if works else []


def write_with_lerobot(
    folder: Path,
    tmp_path: Path,
    arrays: dict[str, np.ndarray],
    fps: int = 1,
    video: bool = False,
    names: dict[str, list[str]] | None = None,
    vcodec: str = "libsvtav1",
) -> Path:
    """LeRobot's own writer makes `folder` from `arrays` (one per feature, row i frame i; uint8 (N, H, W, 3) a
    camera, as PNG images or with video=True a video; plus "episode_index" and "task" per frame); see write.py."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    src = Path(tempfile.mkstemp(suffix=".npz", prefix="lerobot-write-", dir=tmp_path)[1])
    extra = {"__names__": np.array(json.dumps(names))} if names else {}
    with open(src, "wb") as f:
        np.savez(f, **arrays, **extra)
    cmd = [*_no_real_time(), sys.executable, str(WRITE_SCRIPT), str(folder), str(src), "--fps", str(fps)]
    cmd += ["--vcodec", vcodec] + (["--video"] if video else [])
    done = subprocess.run(cmd, env=reader_env(tmp_path, "pyav"), capture_output=True, text=True, timeout=READ_TIMEOUT_S)
    if done.returncode != 0:
        raise AssertionError(f"LeRobot's writer failed on {folder} (exit {done.returncode}):\n{done.stderr[-6000:]}")
    return folder


_HF_LOAD = """
import sys, numpy as np, datasets
datasets.disable_progress_bars()
ds = datasets.load_dataset("parquet", data_files=sys.argv[1], split="train", cache_dir=sys.argv[2])
cols = {}
for name, values in ds.with_format("numpy")[:].items():
    values = np.asarray(values)
    cols[name] = np.array([str(v) for v in values], dtype=str) if values.dtype == object else values
cols["__features__"] = np.array(repr(ds.features))
np.savez(sys.argv[3], **cols)
"""


def load_with_hf_datasets(folder: Path, tmp_path: Path) -> dict[str, np.ndarray]:
    """datasets.load_dataset("parquet", data_files=folder/data/*/*.parquet, split="train"), offline, in a process
    of its own: each column as numpy (lists of numbers as 2-D arrays), and "__features__": the repr of the
    features `datasets` inferred from the files."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    out = Path(tempfile.mkstemp(suffix=".npz", prefix="hf-load-", dir=tmp_path)[1])
    files = str(Path(folder) / "data" / "*" / "*.parquet")
    cmd = [sys.executable, "-c", _HF_LOAD, files, str(tmp_path / "hf-datasets-cache"), str(out)]
    done = subprocess.run(cmd, env=reader_env(tmp_path, "pyav"), capture_output=True, text=True, timeout=READ_TIMEOUT_S)
    if done.returncode != 0:
        raise AssertionError(
            f"datasets.load_dataset failed on {files} (exit {done.returncode}):\n{done.stderr[-6000:]}"
        )
    return _load(out)


@functools.cache
def lerobot_available() -> str | None:
    """None when LeRobot's reader and its dependencies are installed and torchcodec loads FFmpeg; else why not.
    (Importing the reader itself is left to the tests, whose failures show its error: it would cost 2 s more.)"""
    needed = ("ledataset:lerobot-dataset", "datasets", "pandas", "pyarrow", "av", "huggingface_hub", "torchcodec")
    for module, _, package in (name.partition(":") for name in needed):
        if importlib.util.find_spec(module) is None:
            return f"{package or module} is not installed (scripts/setup.sh installs LeRobot's reader)"
    probe = "import torchcodec.decoders"
    with tempfile.TemporaryDirectory(prefix="lerobot-probe-") as tmp:
        try:
            env = reader_env(Path(tmp), "torchcodec")
        except RuntimeError as e:
            return str(e)
        done = subprocess.run(
            [sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=READ_TIMEOUT_S
        )
    if done.returncode != 0:
        last = done.stderr.strip().splitlines()[-1:] or ["(no output)"]
        return f"LeRobot's reader does not import ({probe}): {last[0]}"
    return None


def require_lerobot() -> None:
    """Skip the calling test with the reason when the reader is not usable, outside CI; in CI fail instead."""
    reason = lerobot_available()
    if reason is None:
        return
    if os.environ.get("CI", "").lower() not in ("", "0", "false"):  # as tests/test_console.py tells CI
        pytest.fail(f"CI: LeRobot's reader must be usable: {reason}")
    pytest.skip(reason)
