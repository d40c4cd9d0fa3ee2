"""The force-response measures recover known responses on synthetic frames (no network)."""

import math

import numpy as np
import pytest

from model import force_sweep as F

SIZE = 64
MM_PER_PX = 0.1
GREY = 100
RADIUS_PX_PER_N3 = 6.0  # disk radius = 6 px × F^(1/3): Hertz's a ∝ F^(1/3)
SHIFT_PX_PER_N = 3.0  # the contact slides 3 px per N of Fx


def disk(radius_px: float, shift_px: float = 0.0, gain: float = 60.0) -> np.ndarray:
    img = np.full((SIZE, SIZE, 3), GREY, np.uint8)
    rows, cols = np.mgrid[:SIZE, :SIZE]  # pixel centres within the radius: area ≈ π r², sub-pixel exact
    inside = (cols - (SIZE - 1) / 2 - shift_px) ** 2 + (rows - (SIZE - 1) / 2) ** 2 <= radius_px**2
    img[inside] = GREY + gain
    return img


def hertz(wrench: np.ndarray) -> np.ndarray:
    fz = max(0.0, float(wrench[2]))
    return disk(RADIUS_PX_PER_N3 * fz ** (1 / 3), SHIFT_PX_PER_N * float(wrench[0]))


NO_CONTACT = np.full((SIZE, SIZE, 3), GREY, np.uint8)


def sweep(generator, component, values, references=None, base=(0.0, 0.0, 2.0, 0.0, 0.0, 0.0), blur_px=1.0):
    refs = references if references is not None else [(None, "")] * len(values)
    return F.sweep_pose(
        lambda p, wrenches: [generator(w) for w in wrenches],
        0,
        component,
        np.asarray(values, dtype=float),
        np.asarray(base),
        no_contact=NO_CONTACT,
        mm_per_px=MM_PER_PX,
        references=refs,
        blur_px=blur_px,
    )


def test_area_centroid_and_shading_of_a_disk():
    m = F.measure_contact(disk(10, shift_px=5), NO_CONTACT, mm_per_px=MM_PER_PX, blur_px=0)
    assert m.area_px == pytest.approx(math.pi * 10**2, rel=0.08)
    assert m.area_mm2 == pytest.approx(m.area_px * MM_PER_PX**2)
    assert m.centroid_x_mm == pytest.approx(0.5, abs=0.06) and m.centroid_y_mm == pytest.approx(0.0, abs=0.06)
    assert m.shading == pytest.approx(60.0, abs=0.5)
    none = F.measure_contact(NO_CONTACT, NO_CONTACT, mm_per_px=MM_PER_PX)
    assert none.area_px == 0 and math.isnan(none.centroid_x_mm) and none.shading == 0
    with pytest.raises(ValueError, match="mm_per_px"):
        F.measure_contact(NO_CONTACT, NO_CONTACT, mm_per_px=float("nan"))
    with pytest.raises(ValueError, match="differ in shape"):
        F.measure_contact(NO_CONTACT[:10], NO_CONTACT, mm_per_px=MM_PER_PX)


def test_hertz_disks_give_a_monotonic_area_with_exponent_two_thirds():
    values = F.sweep_values(0.5, 16.0, 8)
    s = F.summarise(sweep(hertz, "Fz", values, blur_px=0))
    assert s["area_mm2"]["rho"] == pytest.approx(1.0)
    assert s["monotonic"] and s["area_sign_consistency"] == 1.0
    assert s["area_exponent"] == pytest.approx(2 / 3, abs=0.03)
    assert s["area_mm2"]["slope"] > 0
    # the blur (against noise) widens every edge by about a pixel: the ranking stays, the exponent drops a little
    blurred = F.summarise(sweep(hertz, "Fz", values, blur_px=1.0))
    assert blurred["area_mm2"]["rho"] == pytest.approx(1.0) and 0.5 < blurred["area_exponent"] < 2 / 3


def test_a_sliding_contact_gives_the_centroid_slope():
    values = F.sweep_values(-2.0, 2.0, 5)
    s = F.summarise(sweep(hertz, "Fx", values))
    # 3 px per N at 0.1 mm/px: 0.3 mm per N, rank correlation 1, and the area does not respond
    assert s["centroid_x_mm"]["slope"] == pytest.approx(SHIFT_PX_PER_N * MM_PER_PX, rel=0.1)
    assert s["centroid_x_mm"]["rho"] == pytest.approx(1.0)
    assert abs(s["centroid_y_mm"]["slope"]) < 0.01


def test_a_generator_that_ignores_the_force_is_flagged():
    values = F.sweep_values(0.5, 16.0, 8)
    flat = F.summarise(sweep(lambda w: disk(12), "Fz", values))
    assert math.isnan(flat["area_mm2"]["rho"]) and not flat["monotonic"] and flat["area_sign_consistency"] == 0.0
    shrinking = F.summarise(sweep(lambda w: disk(20 - float(w[2])), "Fz", values))
    assert shrinking["area_mm2"]["rho"] == pytest.approx(-1.0) and not shrinking["monotonic"]
    table = "\n".join(F.component_table([flat], {"Fz": (0.5, 16.0)}))
    assert "| Fz | +0.50 … +16.00 N | 1 | — (no response) |" in table and "| 0/1 |" in table


def test_the_error_against_a_reference_is_the_known_difference():
    values = F.sweep_values(1.0, 8.0, 4)
    bigger = [(disk(RADIUS_PX_PER_N3 * v ** (1 / 3) + 2), "real frame") for v in values[:3]] + [(None, "")]
    s = F.summarise(sweep(hertz, "Fz", values, references=bigger))
    model = np.array(s["model_area_mm2"][:3])
    ref = np.array(s["reference_area_mm2"][:3])
    assert s["references"] == 3 and math.isnan(s["reference_area_mm2"][3])
    assert s["area_mm2"]["mae"] == pytest.approx(np.mean(np.abs(model - ref)))
    assert s["area_mm2"]["mae"] > 0.5  # a radius 2 px larger at 0.1 mm/px: well over half a mm²
    assert s["area_mm2"]["reference_rho"] == pytest.approx(1.0) and s["monotonic"]
    # k compared over the points both have: a radius 2 px larger grows relatively slower, so its k is lower
    assert 0 < s["reference_area_exponent"] < s["area_exponent_matched"]


def test_spearman_slope_and_power_law():
    assert F.spearman([1, 2, 3, 4], [1, 3, 2, 4]) == pytest.approx(0.8)
    assert F.spearman([1, 2, 3, 4], [10, 10, 10, 10]) != F.spearman([1, 2, 3, 4], [10, 10, 10, 10])  # nan
    assert F.spearman([1, 2, 3, 4, 5], [1, 1, 2, 2, 3]) == pytest.approx(9 / math.sqrt(90))  # ties: mean ranks
    assert F.slope([0, 1, 2], [1, 3, 5]) == pytest.approx(2.0)
    f = np.array([1.0, 2.0, 4.0, 8.0])
    assert F.power_exponent(f, 3 * f**0.5) == pytest.approx(0.5)
    assert F.sign_consistency([1, 2, 2, 3], +1) == pytest.approx(2 / 3)


def test_real_frames_are_matched_at_the_pose_and_depth_follows_the_runs_force():
    # a run pressing at two places, four depths each; Fz = 10 N/mm^1.5 × depth^1.5
    depth = np.tile([0.2, 0.4, 0.6, 0.8], 2)
    pose = np.stack([np.repeat([0.0, 1.0], 4), np.zeros(8), -depth, np.zeros(8)], axis=1)
    wrench = np.zeros((8, 6))
    wrench[:, 2] = 10 * depth**1.5
    std = np.ones(6)
    values = np.array([0.5, 2.5, 5.0, 7.2, 20.0])
    found = F.match_real_frames(wrench, pose, 1, 2, values, std)
    # nearest at x = 0 only: 0.89 (frame 0) is within half a step of 0.5, 20 N is beyond the run
    assert found[:4] == [0, 1, 2, 3] and found[4] is None
    assert F.match_real_frames(wrench, pose, 5, 2, values, std)[:4] == [4, 5, 6, 7]
    assert F.depth_for_force(wrench[:, 2], pose[:, 2], 10 * 0.5**1.5) == pytest.approx(-0.5, abs=0.05)
    assert F.depth_for_force(wrench[:, 2], pose[:, 2], 50.0) is None


def test_poses_are_firm_low_shear_and_spread_over_runs():
    n = 20
    wrench = {r: np.zeros((n, 6)) for r in (0, 1)}
    pose = {r: np.zeros((n, 4)) for r in (0, 1)}
    for r in (0, 1):
        wrench[r][:, 2] = np.linspace(0, 10, n)
        wrench[r][:, 0] = np.linspace(3, -3, n) ** 2  # least shear at the middle frames
        pose[r][:, 0] = np.linspace(0, 4, n)
    rows = np.array([[r, f] for r in (0, 1) for f in range(n)])
    chosen = F.choose_poses(rows, wrench.__getitem__, pose.__getitem__, 3, np.ones(6))
    assert [r for r, _ in chosen] == [0, 1, 0]
    fz = np.linspace(0, 10, n)
    assert all(4 <= fz[f] <= 9.5 for _, f in chosen)
    assert abs(pose[0][chosen[0][1], 0] - pose[0][chosen[2][1], 0]) >= 0.5
