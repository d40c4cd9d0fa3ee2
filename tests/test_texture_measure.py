"""The texture measure ranks a frame with the board's texture above the same frame blurred
and above the texture turned: on a synthetic weave pressed into a disc-shaped contact."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from model.evaluation.texture_measure import TextureBand, texture_score

SIZE_PX = 160
MM_PER_PX = 0.05  # 8 mm across
PERIOD_MM = 1.0  # 20 px
BAND = TextureBand(shortest_mm=0.6, longest_mm=1.6, mm_per_px=MM_PER_PX)


def weave(angle_deg: float = 0.0, seed: int = 0, phase_mm: float = 0.0) -> np.ndarray:
    """A grey-background frame with a woven relief shading inside the contact and sensor noise."""
    y, x = np.mgrid[0:SIZE_PX, 0:SIZE_PX] * MM_PER_PX
    a = math.radians(angle_deg)
    u = x * math.cos(a) + y * math.sin(a) + phase_mm
    v = -x * math.sin(a) + y * math.cos(a)
    warp = np.abs(np.sin(math.pi * u / PERIOD_MM))
    weft = np.abs(np.sin(math.pi * v / PERIOD_MM))
    relief = np.maximum(warp, weft)
    frame = 120.0 + 40.0 * relief * contact()
    frame += np.random.default_rng(seed).normal(0.0, 1.0, frame.shape)
    return np.repeat(frame[..., None], 3, axis=2)


def contact() -> np.ndarray:
    y, x = np.mgrid[0:SIZE_PX, 0:SIZE_PX]
    return np.hypot(x - SIZE_PX / 2, y - SIZE_PX / 2) < SIZE_PX * 0.4


def test_the_right_texture_scores_above_the_blurred_and_the_turned_one():
    real = weave(seed=1)
    right = weave(seed=2, phase_mm=0.05)  # same board, other noise, a little shifted
    blurred = cv2.GaussianBlur(right, (0, 0), PERIOD_MM / MM_PER_PX / 3)
    turned = weave(angle_deg=30.0, seed=2)
    s_right, s_blur, s_turn = (texture_score(real, f, contact(), BAND) for f in (right, blurred, turned))

    assert s_right.score > s_blur.score + 0.2, (s_right, s_blur)
    assert s_right.score > s_turn.score + 0.2, (s_right, s_turn)
    # and for the reason each measure names
    assert 0.7 < s_right.power_ratio < 1.4
    assert s_blur.power_ratio < 0.3  # blurring removes the band's power
    assert s_turn.spectrum_corr < s_right.spectrum_corr - 0.2  # turning moves its peaks
    assert s_right.hp_ssim > max(s_blur.hp_ssim, s_turn.hp_ssim) + 0.2
    assert texture_score(real, real, contact(), BAND).score == pytest.approx(1.0)


def test_a_band_the_frame_cannot_show_is_refused_in_one_line():
    coarse = TextureBand(shortest_mm=0.6, longest_mm=1.6, mm_per_px=0.5)  # 1.2 px per shortest period
    with pytest.raises(ValueError, match="cannot show the texture"):
        texture_score(weave(), weave(seed=3), contact(), coarse)


@pytest.mark.parametrize("bad", [float("nan"), -1.0, 0.0, float("inf")])
def test_bad_band_numbers_are_refused(bad):
    with pytest.raises(ValueError, match="expected a finite number > 0"):
        TextureBand(shortest_mm=bad, longest_mm=1.0, mm_per_px=0.05)


def test_a_tiny_contact_or_mismatched_shapes_are_refused():
    tiny = np.zeros((SIZE_PX, SIZE_PX), bool)
    tiny[:4, :4] = True
    with pytest.raises(ValueError, match="expected ≥ 64"):
        texture_score(weave(), weave(seed=3), tiny, BAND)
    with pytest.raises(ValueError, match="differ"):
        texture_score(weave(), weave(seed=3)[:-1], contact(), BAND)


def test_rows_over_frames_rank_the_blurred_contact_below_the_real_texture_and_find_the_contact():
    from model.evaluation.texture_eval import blurred_contact, contact_mask, texture_rows

    background = np.full((SIZE_PX, SIZE_PX, 3), 120.0)
    reals = [weave(seed=s) for s in (1, 2, 3)]
    mask = contact_mask(reals[0], background)
    assert (mask & contact()).sum() / contact().sum() > 0.9  # the pressed disc, found from the frame alone
    assert (mask & ~contact()).sum() < 0.1 * contact().sum()  # the smoothing widens it by a few px
    same = texture_rows(reals, [weave(seed=s + 10) for s in (1, 2, 3)], [background] * 3, BAND)
    coarse = texture_rows(reals, [blurred_contact(r, 24) for r in reals], [background] * 3, BAND)
    assert isinstance(same, dict) and isinstance(coarse, dict)
    mean, low, high = same["texture_score"]
    assert low <= mean <= high
    assert coarse["texture_score"][2] < same["texture_score"][1]  # intervals apart
    unresolved = TextureBand(shortest_mm=0.6, longest_mm=1.6, mm_per_px=0.5)
    assert texture_rows(reals, reals, [background] * 3, unresolved).startswith("not scored: the texture's shortest")
