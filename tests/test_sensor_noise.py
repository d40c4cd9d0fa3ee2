"""The camera's noise: simulated backgrounds have the statistics the profile states, measured the way the
calibration measures real frames; a downscaled frame keeps the camera's noise as downscaled."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sensor_sim.noise import SensorNoise, difference_stats, noise_from_stats
from sensor_sim.optics import Renderer
from sensor_sim.profile import default_profile

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


def profile_with(noise: SensorNoise, size=(320, 240)):
    base = default_profile()
    w, h = size
    background = np.full((h, w, 3), (110, 100, 90), np.uint8)  # flat: only noise differs between frames
    return dataclasses.replace(
        base, width_px=w, height_px=h, mm_per_px=0.06, background=background, noise=noise, format=2
    )


@pytest.mark.parametrize(
    "noise",
    [
        SensorNoise((1.12, 0.68, 0.95), 0.83, (-0.18, -0.08, -0.16)),  # as measured on the GelSight Mini
        SensorNoise((0.88, 0.65, 0.75), 0.69, (0.37, 0.44, 0.39)),  # and on the original GelSight
        SensorNoise((2.0, 2.0, 2.0)),  # independent pixels and channels
    ],
    ids=["mini", "gelsight", "independent"],
)
def test_noise_statistics_of_a_simulated_background_match_the_profile(noise):
    profile = profile_with(noise)
    first = Renderer.from_profile(profile, "rgb", seed=1).render({})
    second = Renderer.from_profile(profile, "rgb", seed=2).render({})
    measured = noise_from_stats(difference_stats(first, second))
    assert measured.std_bgr == pytest.approx(noise.std_bgr, rel=0.06), measured
    assert measured.correlation_px == pytest.approx(noise.correlation_px, abs=0.1), measured
    assert measured.channel_correlation == pytest.approx(noise.channel_correlation, abs=0.05), measured


def test_a_frame_smaller_than_the_camera_gets_the_camera_noise_downscaled():
    """The noise is made at the camera's pixels (the background's) and resized like the background:
    a frame of half the camera's size shows less of it per pixel, not the camera's per-pixel std."""
    noise = SensorNoise((2.0, 2.0, 2.0), 0.8)
    native = profile_with(noise, (320, 240))
    half = dataclasses.replace(native, width_px=160, height_px=120, mm_per_px=0.12)
    full = [Renderer.from_profile(native, "rgb", seed=s).render({}).astype(float) for s in (1, 2)]
    small = [Renderer.from_profile(half, "rgb", seed=s).render({}).astype(float) for s in (1, 2)]
    assert small[0].shape == (120, 160, 3)
    assert np.std(small[0] - small[1]) < 0.9 * np.std(full[0] - full[1])  # correlated: ~0.84, not 0.5


@pytest.mark.skipif(not (SHARED / "gelsight").is_dir(), reason="the real frames are not beside the checkout")
def test_the_real_sensors_noise_is_correlated_and_the_estimate_reproduces_it():
    """Frames of both real sensors away from the contact: neighbour correlation well above an
    independent camera's (~0.2 after the high-pass), and the estimated model, simulated and measured
    again the same way, gives the same statistics back."""
    import cv2

    for name in ("gelsight_mini", "gelsight"):
        folder = SHARED / name
        background = cv2.imread(str(folder / "background.png"), cv2.IMREAD_COLOR)
        press = cv2.imread(str(folder / "press_00.png"), cv2.IMREAD_COLOR)
        h, w = background.shape[:2]
        ys, xs = np.mgrid[0:h, 0:w]
        far = np.hypot(xs - 320, ys - 220) > 200  # both presses are near (320, 220) with radii under 70 px
        real = difference_stats(press, background, far)
        assert real.neighbour_correlation > 0.4, (name, real)
        model = noise_from_stats(real)
        assert model.correlation_px > 0.5
        sim = profile_with(model, (w, h))
        again = difference_stats(
            Renderer.from_profile(sim, "rgb", seed=1).render({}), Renderer.from_profile(sim, "rgb", seed=2).render({})
        )
        assert again.std_bgr == pytest.approx(real.std_bgr, rel=0.08), name
        assert again.neighbour_correlation == pytest.approx(real.neighbour_correlation, abs=0.04), name
