"""The LeRobot harness (tests/lerobot_support.py) itself: a folder written by LeRobot's own writer reads back
through LeRobot's own reader with every value as written (PNG frames exact too), and through Hugging Face
`datasets` the same; a folder it cannot read fails with the reader's error. Outside CI a missing reader
skips with the reason; in CI it fails (scripts/setup.sh installs it)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from lerobot_support import load_with_hf_datasets, read_with_lerobot, require_lerobot, write_with_lerobot

EPISODES = (3, 2)
WRENCH = ["fx_N", "fy_N", "fz_N", "tx_Nmm", "ty_Nmm", "tz_Nmm"]


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> tuple[Path, dict[str, np.ndarray]]:
    require_lerobot()
    rng = np.random.default_rng(7)
    n = sum(EPISODES)
    arrays = {
        "observation.images.tactile": rng.integers(0, 256, (n, 24, 32, 3), dtype=np.uint8),
        "observation.state": rng.normal(size=(n, 4)).astype(np.float32),
        "observation.wrench": rng.normal(size=(n, 6)).astype(np.float32),
        "action": rng.normal(size=(n, 4)).astype(np.float32),
        "episode_index": np.repeat(np.arange(len(EPISODES)), EPISODES),
        "task": np.array([f"press level {e}" for e in np.repeat(np.arange(len(EPISODES)), EPISODES)]),
    }
    tmp = tmp_path_factory.mktemp("lerobot-harness")
    names = {"observation.state": ["x_mm", "y_mm", "z_mm", "theta_deg"], "observation.wrench": WRENCH}
    folder = write_with_lerobot(tmp / "ds", tmp, arrays, fps=10, names=names)
    return folder, arrays


@pytest.mark.slow
def test_lerobot_reads_back_what_its_writer_wrote(written, tmp_path):
    folder, arrays = written
    got = read_with_lerobot(folder, tmp_path)
    n = sum(EPISODES)
    for key in ("observation.state", "observation.wrench", "action"):
        assert got[key].dtype == np.float32 and np.array_equal(got[key], arrays[key]), key
    assert np.array_equal(got["observation.images.tactile"], arrays["observation.images.tactile"])  # PNG: exact
    assert np.array_equal(got["episode_index"], arrays["episode_index"])
    assert np.array_equal(got["index"], np.arange(n))
    assert np.array_equal(got["frame_index"], np.concatenate([np.arange(k) for k in EPISODES]))
    assert np.allclose(got["timestamp"], got["frame_index"] / 10)
    assert list(got["task"]) == list(arrays["task"]) and list(got["meta_tasks"]) == ["press level 0", "press level 1"]
    assert (int(got["num_frames"]), int(got["num_episodes"]), list(got["episodes"])) == (n, 2, [0, 1])
    info = json.loads(str(got["meta_info"]))
    assert info["codebase_version"] == "v3.0" and info["fps"] == 10
    assert info["features"]["observation.wrench"]["names"] == WRENCH
    assert {"observation.wrench", "observation.images.tactile"} <= set(got["meta_stats_keys"])
    stats = json.loads(str(got["meta_stats"]))
    assert np.allclose(stats["observation.wrench"]["mean"], arrays["observation.wrench"].mean(0), atol=1e-6)


@pytest.mark.slow
def test_hf_datasets_reads_the_same_data_files(written, tmp_path):
    folder, arrays = written
    got = load_with_hf_datasets(folder, tmp_path)
    for key in ("observation.state", "observation.wrench", "action"):
        assert np.array_equal(got[key], arrays[key]), key
    assert np.array_equal(got["episode_index"], arrays["episode_index"])
    assert "observation.wrench" in str(got["__features__"])


@pytest.mark.slow
def test_a_folder_the_reader_refuses_fails_with_its_error(written, tmp_path):
    folder, _ = written
    (tmp_path / "broken" / "meta").mkdir(parents=True)
    (tmp_path / "broken" / "meta" / "info.json").write_text("{}")
    with pytest.raises(AssertionError, match="LeRobot's reader failed on .*broken"):
        read_with_lerobot(tmp_path / "broken", tmp_path / "reader")
