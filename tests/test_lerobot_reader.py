"""An export read by the ecosystem's own code: LeRobotDataset (lerobot-dataset, offline, from the folder) gives
every frame, wrench and pose of the run file, Hugging Face `datasets` loads the data parquet, and a dataset
written by LeRobot's own writer (AV1, episodes sharing one video file) imports into run files."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from lerobot_support import load_with_hf_datasets, read_with_lerobot, require_lerobot, write_with_lerobot
from test_lerobot_exchange import _dataset, exported, sim_run  # noqa: F401 (fixtures)

from acquisition import schema as S
from acquisition.run_reader import RunReader
from dataset.lerobot import layout as L

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def by_press(sim_run, tmp_path_factory) -> Path:  # noqa: F811
    require_lerobot()
    out = tmp_path_factory.mktemp("lerobot-press") / "press"
    code, said = _dataset("export", str(sim_run), "--format", "lerobot", "--out", str(out), "--episode", "press")
    assert code == 0, said
    return out


def test_lerobot_reads_every_frame_wrench_and_pose_of_the_run(by_press, sim_run, tmp_path):  # noqa: F811
    got = read_with_lerobot(by_press, tmp_path)
    with RunReader.open(sim_run) as run:
        n = run.n
        assert (int(got["num_frames"]), int(got["num_episodes"])) == (n, 2)
        frames = np.stack([cv2.cvtColor(run.frame(i), cv2.COLOR_BGR2RGB) for i in range(n)])
        assert np.array_equal(got[L.CAMERA], frames)  # lossless: every pixel, as the reader decodes it
        # stored as float64 (the import gets the run's numbers back); the reader hands float32 tensors, as torch does
        for key, field in (
            ("observation.wrench", S.WRENCH),
            ("observation.state", S.POSE_MEASURED),
            ("action", S.POSE_COMMANDED),
            (S.T_FRAME, S.T_FRAME),
        ):
            assert np.array_equal(got[key], run.rows[field].astype(got[key].dtype)), key
        assert np.array_equal(got[S.PHASE_INDEX], run.rows[S.PHASE_INDEX])
        assert np.array_equal(got[L.FRAME_IN_RUN], np.arange(n))
        stream = run.stream
        t = run.rows[S.T_FRAME][7]
        inside = stream[(stream[:, 0] > t - 1.0) & (stream[:, 0] <= t)]
        assert np.array_equal(got[L.WINDOW][7][~got[L.WINDOW_PAD][7]], inside[:, 1:].astype(got[L.WINDOW].dtype))
    assert np.array_equal(got["episode_index"], np.repeat([0, 1], [13, 13]))
    assert np.allclose(got["timestamp"], got["frame_index"])  # 1 frame per second, from 0 in each episode
    assert list(got["meta_tasks"]) == ["two-levels: sphere10mm pressed on a rgb tactile sensor"]
    info = json.loads(str(got["meta_info"]))
    assert info["features"]["observation.state"]["names"] == ["x_mm", "y_mm", "z_mm", "theta_deg"]
    stats = json.loads(str(got["meta_stats"]))
    assert np.allclose(stats["observation.wrench"]["mean"], got["observation.wrench"].mean(0))
    assert np.allclose(stats["observation.wrench"]["std"], got["observation.wrench"].std(0))


def test_hf_datasets_loads_the_data_parquet(by_press, sim_run, tmp_path):  # noqa: F811
    got = load_with_hf_datasets(by_press, tmp_path)
    with RunReader.open(sim_run) as run:
        # `datasets`' numpy format hands floats as float32; the files hold float64, as their features say
        assert np.array_equal(got["observation.wrench"], run.rows[S.WRENCH].astype(got["observation.wrench"].dtype))
        assert np.array_equal(
            got["observation.state"], run.rows[S.POSE_MEASURED].astype(got["observation.state"].dtype)
        )
        assert np.array_equal(got["capture_index"], run.rows[S.CAPTURE_INDEX])
    assert "'observation.wrench': List(Value('float64'), length=6)" in str(got["__features__"])
    assert got[L.WINDOW].shape[1:] == (json.loads((by_press / L.INFO).read_text())["features"][L.WINDOW]["shape"][0], 6)


def test_a_dataset_written_by_lerobot_itself_imports(tmp_path):
    """LeRobot's writer: AV1 at 4:2:0 (its default), both episodes in one video and one data file."""
    require_lerobot()
    rng = np.random.default_rng(3)
    n = (4, 3)
    base = cv2.GaussianBlur(rng.integers(0, 256, (48, 48, 3), dtype=np.uint8), (0, 0), 4)  # smooth, like a gel
    frames = np.stack([np.clip(base.astype(int) + 10 * k, 0, 255).astype(np.uint8) for k in range(sum(n))])
    arrays = {
        "observation.images.tactile": frames,
        "observation.state": rng.normal(size=(sum(n), 4)).astype(np.float32),
        "observation.wrench": rng.normal(size=(sum(n), 6)).astype(np.float32),
        "episode_index": np.repeat([0, 1], n),
        "task": np.array(["press"] * sum(n)),
    }
    folder = write_with_lerobot(tmp_path / "theirs", tmp_path, arrays, fps=2, video=True)
    face = tmp_path / "face.png"
    cv2.imwrite(str(face), np.full((48, 48, 3), 128, np.uint8))
    out = tmp_path / "runs"
    code, said = _dataset(
        "import",
        str(folder),
        "--format",
        "lerobot",
        "--out",
        str(out),
        "--object-image",
        str(face),
        "--mm-per-px",
        "0.05",
        "--sensor",
        "rgb",
    )
    assert code == 0, said
    at = 0
    for e, k in enumerate(n):
        with RunReader.open(out / f"episode_{e:06d}.h5") as run:
            assert run.n == k and run.number(S.ATTR_CAPTURE_HZ) == 2
            assert np.array_equal(run.rows[S.WRENCH], arrays["observation.wrench"][at : at + k].astype(np.float64))
            assert np.array_equal(run.rows[S.POSE_MEASURED], arrays["observation.state"][at : at + k].astype(float))
            for i in range(k):  # the episode's own frames (from its span of the shared video), within AV1's error
                rgb = cv2.cvtColor(run.frame(i), cv2.COLOR_BGR2RGB).astype(float)
                assert np.mean((rgb - frames[at + i]) ** 2) < 30, (e, i)
        at += k
