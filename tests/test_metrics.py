"""Evaluation metrics against their definitions and scikit-image; marker error on rendered markers."""

import math

import cv2
import numpy as np
import pytest

from model.evaluation.markers import find_markers, marker_error
from model.evaluation.metrics import image_metrics, mae, mse, psnr, ssim


@pytest.fixture
def pair():
    rng = np.random.default_rng(0)
    a = rng.integers(0, 256, (64, 80, 3), dtype=np.uint8)
    b = np.clip(a.astype(int) + rng.normal(0, 12, a.shape), 0, 255).astype(np.uint8)
    return a, b


def test_mse_mae_psnr_definitions(pair):
    a, b = pair
    d = a.astype(float) - b
    assert mse(a, b) == pytest.approx((d**2).mean())
    assert mae(a, b) == pytest.approx(np.abs(d).mean())
    assert psnr(a, b) == pytest.approx(10 * math.log10(255**2 / (d**2).mean()))
    assert psnr(a, a) == math.inf and mse(a, a) == 0


def test_ssim_matches_scikit_image_with_the_reference_settings(pair):
    from skimage.metrics import structural_similarity

    a, b = pair
    expected = structural_similarity(
        a, b, gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=255, channel_axis=2
    )
    assert ssim(a, b) == pytest.approx(expected, abs=1e-6)
    assert ssim(a, a) == pytest.approx(1.0)


def test_shape_mismatch_is_an_error(pair):
    with pytest.raises(ValueError, match="differ in shape"):
        image_metrics(pair[0], pair[0][:10])


def test_marker_error_measures_a_known_displacement():
    from objects.pose import Pose
    from sensor_sim.light import OpticsSpec
    from sensor_sim.scene import Scene

    scene = Scene("sphere10mm", "rgb_markers", optics=OpticsSpec(kind="rgb_markers", noise_std=0.0))
    still = scene.frame(Pose(0, 0, 0.5, 0)).image  # no contact: markers at rest
    markers = find_markers(still)
    assert len(markers) == 400  # the whole 20×20 grid is found
    same = marker_error(still, still)
    assert same.total_px == pytest.approx(0.0, abs=1e-6) and same.matched == 324
    shifted = np.roll(still, 2, axis=1)  # every marker 2 px to the right
    err = marker_error(still, shifted)
    assert err.per_marker_px == pytest.approx(2.0, abs=0.05) and err.total_px == pytest.approx(648, rel=0.03)
    pressed = scene.frame(Pose(0.3, 0, -1.0, 0)).image
    moved = scene.contact.solver.solve(Pose(0.3, 0, -1.0, 0), shift_mm=(0.3, 0.0), fields={"uz", "uxy"})
    moved_px = marker_error(still, scene.renderer.render(moved.fields)).per_marker_px
    assert moved_px > marker_error(still, pressed).per_marker_px


def test_markers_inside_a_dark_ring_are_found():
    """A flat punch's dark rim is one ring-shaped blob around the contact: too large to be a
    marker, and the markers inside it are still markers (taking only outermost contours lost them)."""
    img = np.full((128, 128), 200, np.uint8)
    centres = [(8 + 12 * i, 8 + 12 * j) for i in range(10) for j in range(10)]
    for x, y in centres:
        cv2.circle(img, (x, y), 2, 40, -1)
    cv2.rectangle(img, (30, 30), (90, 90), 40, 3)  # the rim, through a column of markers
    found = find_markers(img)
    inside = [(x, y) for x, y in centres if 34 < x < 86 and 34 < y < 86]
    assert len(inside) == 16
    for x, y in inside:
        assert np.min(np.hypot(found[:, 0] - x, found[:, 1] - y)) < 0.5
    assert not np.any((np.abs(found[:, 0] - 60) < 4) & (np.abs(found[:, 1] - 60) < 4))  # no ring centroid


def test_marker_flow_and_its_figure(tmp_path):
    from model.evaluation.evaluate import Evaluation, Row
    from model.evaluation.figures import marker_flow_figure
    from model.evaluation.markers import marker_flow
    from objects.pose import Pose
    from sensor_sim.light import OpticsSpec
    from sensor_sim.scene import Scene

    scene = Scene("sphere10mm", "rgb_markers", optics=OpticsSpec(kind="rgb_markers", noise_std=0.0))
    still = scene.frame(Pose(0, 0, 0.5, 0)).image
    start, end = marker_flow(still, np.roll(still, (1, 3), axis=(0, 1)))  # 3 px right, 1 px down
    assert len(start) == 324
    assert np.allclose((end - start).mean(axis=0), (3.0, 1.0), atol=0.05)
    sheared = scene.renderer.render(
        scene.contact.solver.solve(Pose(0, 0, -1.0, 0), shift_mm=(0.4, 0.0), fields={"uz", "uxy"}).fields
    )
    row = Row("ddim, 10 steps", 1.0, 1.0, 0.9, 40.0, 0.5, 0.01, 1)
    ev = Evaluation([row], None, "", True, examples={"real": [sheared], "ddim, 10 steps": [still]}, references=[still])
    assert marker_flow_figure(ev, tmp_path / "flow.png")
    flow = cv2.imread(str(tmp_path / "flow.png"))
    assert flow.shape[1] == 2 * still.shape[1]  # real and model panels side by side
    blank = Evaluation(
        [row], None, "", True, examples={"real": [np.zeros_like(still)], "ddim, 10 steps": [still]}, references=[still]
    )
    assert not marker_flow_figure(blank, tmp_path / "none.png")  # no markers: no figure, no crash


# -- verdicts that follow the intervals (issue 37) ------------------------------------------------
def _row(setting, mse, mae, ssim, psnr, width=0.1):
    from model.evaluation.eval_results import Row

    ci = {
        k: (v - width * abs(v), v + width * abs(v))
        for k, v in (("mse", mse), ("mae", mae), ("ssim", ssim), ("psnr", psnr))
    }
    return Row(setting, mse, mae, ssim, psnr, None, 0.01, 100, ci=ci)


def _evaluation(model, baselines, physics=None, simulated=False):
    from model.evaluation.eval_results import Evaluation

    return Evaluation([model], physics, "", False, simulated=simulated, baselines=baselines)


def test_a_model_better_on_mse_and_worse_on_mae_is_called_so_metric_by_metric():
    from model.evaluation.evaluation_report import metrics_verdict

    model = _row("ddim:10", mse=2.0, mae=2.09, ssim=0.90, psnr=39.1, width=0.02)
    nearest = _row("nearest training frame", mse=4.0, mae=1.41, ssim=0.90, psnr=41.85, width=0.02)
    text = metrics_verdict(_evaluation(model, [nearest]))
    assert "MSE **better** than nearest training frame" in text
    assert "MAE **worse** than nearest training frame" in text and "PSNR **worse**" in text
    assert "SSIM **tied** with" in text  # the same value: intervals overlap
    assert "beats" not in text


def test_overlapping_intervals_read_tied_and_the_oracle_is_apart():
    from model.evaluation.evaluation_report import metrics_verdict

    model = _row("ddim:10", mse=87.4, mae=5.0, ssim=0.8, psnr=30.0, width=0.1)
    nearest = _row("nearest training frame", mse=89.9, mae=5.2, ssim=0.79, psnr=29.8, width=0.2)
    render = _row("physics render", mse=0.5, mae=0.3, ssim=0.99, psnr=50.0, width=0.01)
    text = metrics_verdict(_evaluation(model, [nearest], physics=render, simulated=True))
    assert "MSE **tied** with nearest training frame (87.40 [" in text
    assert "physics render is an oracle on simulated frames" in text and "than physics render" not in text
    real = metrics_verdict(_evaluation(model, [nearest], physics=render, simulated=False))
    assert "MSE **worse** than physics render" in real  # on real frames it is a baseline like the others


# -- near the contact, and light loads (issue 37) -------------------------------------------------
def _disk_frame(radius_px: float, centre=(32, 32), size=64, gain=80.0, base=None):
    yy, xx = np.mgrid[:size, :size]
    frame = np.full((size, size, 3), 120.0) if base is None else base.astype(np.float64).copy()
    inside = (yy - centre[1]) ** 2 + (xx - centre[0]) ** 2 <= radius_px**2
    frame[inside] += gain
    return np.clip(frame, 0, 255).astype(np.uint8)


def test_near_contact_metrics_see_the_contact_that_the_whole_frame_dilutes():
    from model.evaluation.contact_scores import find_contacts, near_row
    from model.evaluation.metrics import image_metrics

    rng = np.random.default_rng(0)
    background = np.full((64, 64, 3), 120, np.uint8)
    real = [_disk_frame(6, (20 + 3 * i, 30)) for i in range(4)] + [background.copy()]
    wrong = [_disk_frame(12, (20 + 3 * i, 30)) for i in range(4)] + [background.copy()]  # contact twice too wide
    noisy = [np.clip(r + rng.normal(0, 3, r.shape), 0, 255).astype(np.uint8) for r in real]
    contacts = find_contacts(real, [background] * 5, [0.1] * 5, [1.0] * 5, blur_px=1.0, radius_mm=1.0)
    assert contacts.seen == 4 and contacts.regions[4] is None  # the untouched frame has no near value
    region = contacts.regions[0]
    assert region is not None and region[30, 20] and not region[5, 60]  # around the contact, not the corner
    assert 0.8 * np.pi * 16**2 < region.sum() < 1.2 * np.pi * 16**2  # 6 px + 1 mm / 0.1 mm per px
    whole = np.mean([image_metrics(r, w)["mse"] for r, w in zip(real, wrong)])
    near = near_row("wrong", real, wrong, contacts)
    assert near is not None and near.images == 4
    assert near.mse > 2.5 * whole  # the background no longer dilutes the error
    good = near_row("noisy", real, noisy, contacts)
    assert good is not None and good.mse < near.mse and good.ci["mse"][1] < near.ci["mse"][0]
    assert 0 < good.ssim <= 1 and near.psnr < good.psnr


def test_the_light_load_row_reads_a_contact_twice_too_large_as_about_two():
    from model.evaluation.contact_scores import find_contacts, light_frames, light_load

    background = np.full((64, 64, 3), 120, np.uint8)
    fz = [0.04, 0.05, 0.06, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 6.0, 7.0, -0.01]
    radius = [3 + 2 * f for f in fz]
    real = [_disk_frame(r, (30, 30)) for r in radius]
    contacts = find_contacts(real, [background] * len(fz), [0.1] * len(fz), fz, blur_px=0.0)
    assert light_frames(contacts) == [0, 1, 2]  # the lightest pressed frames (20 % of 15 is 3), not Fz < 0
    same = light_load("same", real, contacts)
    assert same is not None and same["ratio"] == pytest.approx(1.0, abs=0.02)
    grown = [_disk_frame(r * np.sqrt(2), (30, 30)) for r in radius]  # area × 2
    twice = light_load("twice", grown, contacts)
    assert twice is not None and twice["ratio"] == pytest.approx(2.0, abs=0.25)
    assert twice["ratio_ci"][0] > 1.5 and twice["fz_low_N"] == 0.04 and twice["fz_high_N"] == 0.06


def test_a_test_part_of_named_runs_says_which_runs_and_never_trained_on():
    from model.evaluation.eval_results import Evaluation
    from model.evaluation.evaluation_report import part_text

    ev = Evaluation([], None, "", False, part="test", test_runs=["/data/runs/central_band.h5"])
    assert part_text(ev) == (
        "the runs named for the test part (dataset split --test-runs: central_band.h5), never trained on"
    )
    assert part_text(Evaluation([], None, "", False, part="test")) == "unseen frames of the training objects"
