"""Figure labels are wrapped to the figure's width, never cut off (model/evaluation/figures.py)."""

from __future__ import annotations

import numpy as np

from model.evaluation.figures import samples_figure, wrapped

LABEL = "Fz 1.41 N  Fx +0.00 N  Fy +0.00 N  Mz +0.0 N·mm | x -3.90  y +3.17  z -1.74 mm  θ +0.0°"


def test_a_label_wider_than_the_figure_is_wrapped_with_every_word_kept():
    lines = wrapped(LABEL, 652)  # four 160 px columns: the samples figure of an evaluation
    assert len(lines) == 2 and all(len(line) <= 652 // 8 for line in lines)
    assert " ".join(" ".join(lines).replace("|", " ").split()) == " ".join(LABEL.replace("|", " ").split())
    assert lines[-1].endswith("θ +0.0°")
    assert wrapped("Fz 1.41 N", 652) == ["Fz 1.41 N"]
    narrow = wrapped(LABEL, 40)  # 5 characters a line: a word a line, none cut
    assert all(len(line) <= 5 or " " not in line for line in narrow) and "θ" in narrow[-2]


def test_the_samples_figure_gives_a_wrapped_label_its_own_strips(tmp_path):
    import cv2

    tiles = {name: [np.full((32, 32, 3), 128, np.uint8)] * 2 for name in ("object", "real", "render", "model")}
    samples_figure(tiles, tmp_path / "short.png", ["Fz 1 N", "Fz 2 N"])
    samples_figure(tiles, tmp_path / "long.png", [LABEL, LABEL])
    short, long = (cv2.imread(str(tmp_path / f"{n}.png")) for n in ("short", "long"))
    assert long.shape[0] == short.shape[0] + 2 * 22 and long.shape[1] == short.shape[1]


def test_an_example_label_has_units_and_no_negative_zero():
    import torch

    from model.evaluation.evaluate import _label

    class Data:
        std, mean = np.ones(6), np.zeros(6)

    item = {
        "wrench": torch.tensor([-1e-9, 0.004, 1.5, 0, 0, -0.04]),
        "pose": torch.tensor([-9.125e-06, 3.17, -1.74, -0.01]),
    }
    label = _label(Data(), item)  # type: ignore[arg-type]
    assert label == "Fz 1.50 N  Fx +0.00 N  Fy +0.00 N  Mz +0.0 N·mm | x +0.00  y +3.17  z -1.74 mm  θ +0.0°"
