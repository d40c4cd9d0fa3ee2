"""Where everything lives in a LeRobotDataset v3.0 folder, and which run-file field each feature holds.

    meta/info.json                       format version, fps, counts, paths, the features (dtype, shape, names)
    meta/stats.json                      min, max, mean, std, count and quantiles of every numeric feature
    meta/tasks.parquet                   the task strings (index) and their task_index
    meta/episodes/chunk-000/file-000.parquet   per episode: length, tasks, its rows and its video's span
    data/chunk-000/file-NNN.parquet      one row per frame (one file per episode)
    videos/observation.images.tactile/chunk-000/file-NNN.mp4   the tactile frames (one file per episode)
    meta/tactile/                        this project's part: what the ecosystem's reader does not read
      export.json                        the source runs, each episode's run and frames, digests of every file
      runs/run-NNN/                      each source run's attributes (run.json), object.png, reference.png,
                                         its full-rate wrench stream (wrench_stream.npy)
      episodes/episode-NNNNNN/object.png the contact condition, once per episode (with condition.json)

Episode ``i`` is file ``i % 1000`` of chunk ``i // 1000``, in data/ and videos/ alike.
"""

from __future__ import annotations

from pathlib import Path

from acquisition import schema as S

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000
CAMERA = "observation.images.tactile"
INFO = "meta/info.json"
STATS = "meta/stats.json"
TASKS = "meta/tasks.parquet"
EPISODES = "meta/episodes/chunk-000/file-000.parquet"
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
TACTILE = "meta/tactile"
EXPORT_JSON = f"{TACTILE}/export.json"
FORMAT_MARK = "tactile-rig lerobot export 1"  # export.json's "format": what import knows how to read back

# run-file field -> (feature name, dtype in the folder). Vectors keep their names from the field table;
# float64 is the run file's own precision, so a round trip gives the same numbers.
FEATURE_OF = {
    S.POSE_MEASURED: "observation.state",
    S.POSE_COMMANDED: "action",
    S.WRENCH: "observation.wrench",
}
WINDOW = "observation.wrench_window"  # (W, 6): the gauge's full-rate samples in the capture period up to the frame
WINDOW_T = "observation.wrench_window_t_s"  # (W,): each sample's time from the frame, s (<= 0)
WINDOW_PAD = "observation.wrench_window_is_pad"  # (W,): True where the window is padded (fewer samples came)
FRAME_IN_RUN = "frame_in_run"  # the frame's index in its source run
DEFAULT_FEATURES = {
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    "frame_index": {"dtype": "int64", "shape": [1], "names": None},
    "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    "index": {"dtype": "int64", "shape": [1], "names": None},
    "task_index": {"dtype": "int64", "shape": [1], "names": None},
}


def feature_name(field: S.Field) -> str:
    return FEATURE_OF.get(field.path, field.path)


def field_feature(field: S.Field) -> dict:
    """The info.json entry of a per-frame run-file field."""
    kind = "float64" if field.dtype.startswith("f") else "int64"
    shape = list(field.shape) or [1]
    return {"dtype": kind, "shape": shape, "names": list(S.columns_of(field)) if field.shape else [field.path]}


def camera_feature(height: int, width: int, fps: int, codec_info: dict) -> dict:
    return {
        "dtype": "video",
        "shape": [height, width, 3],
        "names": ["height", "width", "channels"],
        "info": {
            "video.height": height,
            "video.width": width,
            "video.codec": codec_info["codec"],
            "video.pix_fmt": codec_info["pix_fmt"],
            "video.is_depth_map": False,
            "video.fps": fps,
            "video.channels": 3,
            "has_audio": False,
        },
    }


def window_features(width: int) -> dict:
    wrench = list(S.columns_of(S.FIELD[S.WRENCH]))  # the last axis; the first is the sample, oldest first
    return {
        WINDOW: {"dtype": "float64", "shape": [width, 6], "names": wrench},
        WINDOW_T: {"dtype": "float64", "shape": [width], "names": [f"t{i}_s" for i in range(width)]},
        WINDOW_PAD: {"dtype": "bool", "shape": [width], "names": [f"pad{i}" for i in range(width)]},
    }


def data_file(episode: int) -> str:
    return DATA_PATH.format(chunk_index=episode // CHUNKS_SIZE, file_index=episode % CHUNKS_SIZE)


def video_file(episode: int) -> str:
    return VIDEO_PATH.format(video_key=CAMERA, chunk_index=episode // CHUNKS_SIZE, file_index=episode % CHUNKS_SIZE)


def run_folder(run: int) -> str:
    return f"{TACTILE}/runs/run-{run:03d}"


def episode_folder(episode: int) -> str:
    return f"{TACTILE}/episodes/episode-{episode:06d}"


def relative_files(folder: Path) -> list[str]:
    """Every file under ``folder``, relative, sorted (what export.json's digests cover, itself aside)."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file() and p.name != "export.json")
