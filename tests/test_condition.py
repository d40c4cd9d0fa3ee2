"""The condition `generate` builds equals the one training builds for the same run frame."""

from __future__ import annotations

import cv2
import h5py
import numpy as np
import pytest

from acquisition import schema as S
from tests.test_model_core import make_split_dir


def _centroid(img: np.ndarray) -> np.ndarray:
    w = img.astype(float).sum(axis=2)
    ys, xs = np.indices(w.shape)
    return np.array([(xs * w).sum(), (ys * w).sum()]) / w.sum()


def _model(size: int, mm_per_px: float, frame_px: int):
    from model.denoiser.config import ModelConfig
    from model.generation.inference import TrainedModel

    cfg = ModelConfig(image_size=size, block_out_channels=(16, 16))
    return TrainedModel(None, None, cfg, np.zeros(6), np.ones(6), mm_per_px, frame_px, None)


@pytest.mark.parametrize("frame_px,size", [(64, 16), (32, 32)])
def test_generate_condition_equals_training_condition(tmp_path, frame_px, size):
    from dataset.torch_dataset import TactileDataset, uint8_tensor_to_image

    split = make_split_dir(tmp_path, n=24, size=frame_px)
    data = TactileDataset(split, "train", size=size)
    model = _model(size, data.mm_per_px[0], frame_px)
    with h5py.File(data.runs[0], "r") as f:
        obj = f[S.OBJECT_IMAGE][()]
    for i in range(len(data)):
        item = data[i]
        x, y, _, theta = item["pose"].numpy().astype(float)
        built = model.condition(obj, (x, y, theta))
        assert np.array_equal(built, uint8_tensor_to_image(item["condition"]))


def test_a_photo_at_another_resolution_moves_as_far_as_in_training(tmp_path):
    """1 mm of pose moves the condition by 1 mm in model pixels, whatever the photo's size
    (it moved about eight times too far when the scale used the model's size)."""
    frame_px, size, mm_per_px = 64, 16, 14 / 64
    split = make_split_dir(tmp_path, n=24, size=frame_px)
    from dataset.torch_dataset import TactileDataset

    data = TactileDataset(split, "train", size=size)
    with h5py.File(data.runs[0], "r") as f:
        obj = f[S.OBJECT_IMAGE][()]
    model = _model(size, mm_per_px, frame_px)
    photo = cv2.resize(obj, (3 * frame_px, 3 * frame_px), interpolation=cv2.INTER_LINEAR)
    expected_px = 1.0 / (mm_per_px * frame_px / size)
    for image in (obj, photo):
        shift = _centroid(model.condition(image, (1.0, 0.0, 0.0))) - _centroid(model.condition(image, (0, 0, 0)))
        assert shift[0] == pytest.approx(expected_px, abs=0.1)
        assert abs(shift[1]) < 0.05


def test_a_non_square_object_image_is_refused(tmp_path):
    model = _model(16, 14 / 64, 64)
    with pytest.raises(ValueError, match="expected a square image"):
        model.condition(np.zeros((40, 60, 3), np.uint8), (0, 0, 0))


@pytest.mark.parametrize("frame_px,size,kind", [(64, 16, "rgb"), (16, 16, "rgb"), (64, 32, "rgb_markers")])
def test_generate_physics_channels_equal_training_ones(tmp_path, frame_px, size, kind):
    """A physics model's extra channels: the training cache's render of a run frame, the one
    `generate` renders from the checkpoint's record for the object at that pose and wrench, and
    the one evaluate's plain items get, are the same image."""
    from dataclasses import replace

    import h5py

    from acquisition import schema as S
    from dataset.torch_dataset import TactileDataset, uint8_tensor_to_image
    from model.conditioning.physics_condition import physics_cache, split_spec
    from model.generation.inference import add_physics

    split = make_split_dir(tmp_path, n=24, size=frame_px, kind=kind)
    data = TactileDataset(split, "train", size=size, physics=physics_cache(split, "train", size))
    plain = TactileDataset(split, "train", size=size)
    model = _model(size, data.mm_per_px[0], frame_px)
    model.cfg = replace(model.cfg, conditioning="physics+plane")
    model.physics = split_spec(split)
    items = [plain[i] for i in range(len(plain))]
    add_physics(items, size, model.physics)
    with h5py.File(data.runs[0], "r") as f:
        recorded = f[S.WRENCH][()]
    for i in range(len(data)):
        cached = uint8_tensor_to_image(data[i]["physics"])
        wrench = recorded[int(data[i]["frame"])]
        assert np.array_equal(model.physics_image("sphere10mm", data[i]["pose"].numpy(), wrench), cached)
        assert np.array_equal(uint8_tensor_to_image(items[i]["physics"]), cached)
