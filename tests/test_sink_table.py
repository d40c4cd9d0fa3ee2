"""Issue 40: the pressed-in gel answers a tilt differently from the gel around the contact at the same normal
(the sink table, profile format 5: per mm of sink, a table over the normal)."""

import dataclasses

import numpy as np
import pytest

from objects.indenters import sphere
from sensor_sim.calibration import fit_optics, provisional_profile
from sensor_sim.light import LightModel
from sensor_sim.light_fit import PressSamples
from sensor_sim.light_sink_table import sink_table_choice
from sensor_sim.light_tables import normal_lookup
from sensor_sim.press_render import PressRender
from sensor_sim.profile import ProfileError, default_profile, load_profile
from sensor_sim.profile_save import save_profile
from tests.test_calibration import BALL_MM, GEL, MM_PER_PX, background, lambertian_table, synthetic_presses

GAIN_PER_MM = -0.5  # the truth's tables, pressed in: T(n) · (1 + GAIN_PER_MM · sink)


def centre_light(bg: np.ndarray) -> LightModel:
    """Lambertian lights whose response to a tilt weakens where the gel is pressed in (as the original
    GelSight's does: 44-77 grey levels per unit of normal at the contact's centre, 80-106 around it)."""
    table = lambertian_table().astype(np.float32)
    mean = bg.reshape(-1, 3).mean(axis=0)
    return LightModel(
        table,
        0.12,
        "multiplicative",
        (float(mean[0]), float(mean[1]), float(mean[2])),
        sink_bgr=np.array([[4.0, 0.0, 0.0], [-3.0, 0.0, 0.0], [5.0, 0.0, 0.0]], np.float32),
        position_scale_mm=1.0,
        sink_table_bgr=GAIN_PER_MM * table,
    )


def centre_error(render: PressRender, truth: PressRender, x: float, y: float, depth: float) -> float:
    """Mean |render − truth| within 0.4 contact radii of the contact's centre (issue 40's measure)."""
    pose = truth.pose_of_pixel(x, y, -depth)
    want, got = truth.render(pose).astype(np.float32), render.render(pose).astype(np.float32)
    area = truth.solve(pose, fields=frozenset()).normal.contact_area_mm2
    radius_px = np.sqrt(area / np.pi) / MM_PER_PX
    ys, xs = np.mgrid[0 : want.shape[0], 0 : want.shape[1]]
    centre = np.hypot(xs - x, ys - y) < 0.4 * radius_px
    return float(np.abs(got - want)[centre].mean())


def test_a_centre_that_answers_a_tilt_more_weakly_is_fitted_with_the_sink_table():
    """Four presses of a sensor whose pressed-in gel answers a tilt half as strongly per mm of sink: leaving
    presses out takes the sink table, and a press at a place and depth none showed is rendered at its centre
    with under half the error of the same light without it (measured 0.79 against 2.45 grey levels; the
    calibration before the sink table: 2.49): one table over the normal splits the difference between the
    contact's centre and the gel around it."""
    bg = background()
    places = [(160.3, 120.6, 1.2), (80.8, 75.2, 1.4), (242.1, 80.7, 1.0), (88.4, 166.9, 1.3)]
    truth, presses = synthetic_presses(centre_light(bg), bg, places, 11)
    fit = fit_optics(bg, presses, MM_PER_PX, gel=GEL)
    assert fit.sink_table and fit.light.sink_table_bgr is not None and fit.light.profile_format == 5
    assert np.all(fit.light.sink_table_bgr[:, 10, 10] == 0)  # the flat normal's sink change is the sink terms'
    without = dataclasses.replace(fit.light, sink_table_bgr=None)
    fitted, plain = (
        PressRender(provisional_profile(bg, MM_PER_PX, GEL, light), sphere(2 * BALL_MM))
        for light in (fit.light, without)
    )
    with_table = centre_error(fitted, truth, 230.0, 170.0, 1.25)
    alone = centre_error(plain, truth, 230.0, 170.0, 1.25)
    assert with_table < min(0.5 * alone, 1.2), (with_table, alone)


def test_one_press_or_presses_without_centre_pixels_take_no_sink_table():
    rng = np.random.default_rng(3)
    gx, gy = rng.normal(0, 0.3, 500), rng.normal(0, 0.3, 500)
    idx, w = normal_lookup(gx, gy, 21)
    zeros = np.zeros(500)
    change = np.stack([30 * gx] * 3, axis=1)
    press = PressSamples(idx, w, zeros, zeros, zeros + 1.0, np.ones((500, 3)), change, zeros == 0, centre=zeros == 0)
    assert not sink_table_choice([press], 21, 0.0)
    no_centre = dataclasses.replace(press, centre=None, matrices={})
    assert not sink_table_choice([no_centre, no_centre], 21, 0.0)


def test_the_sink_table_renders_as_written_and_is_held_at_the_deepest_sink():
    """shade · min(sink, sink_max_mm) · U(n), added to the other terms; U constant here so any normal reads it."""
    h, w = 20, 30
    ref = (100.0, 80.0, 125.0)
    per_mm = np.array([2.0, -3.0, 5.0], np.float32)
    light = LightModel(
        np.zeros((3, 5, 5), np.float32),
        0.0,
        "multiplicative",
        ref,
        sink_bgr=np.zeros((3, 3), np.float32),
        position_scale_mm=1.0,
        sink_max_mm=1.5,
        sink_table_bgr=np.broadcast_to(per_mm[:, None, None], (3, 5, 5)),
    )
    bg = np.full((h, w, 3), 100.0, np.float32)
    planes = light.frame_planes(bg, 3.0, 2.0)
    rng = np.random.default_rng(2)
    gx, gy = (rng.uniform(-0.5, 0.5, (h, w)).astype(np.float32) for _ in range(2))
    sink = np.full((h, w), 1.0, np.float32)
    sink[5, 7] = 2.5  # deeper than any press the light was fitted on: held at 1.5 mm
    got = light.change_frame(gx, gy, sink, planes)
    scale = 100.0 / np.asarray(ref)
    assert got[:, 3, 3] == pytest.approx(per_mm * scale * 1.0, rel=1e-5)
    assert got[:, 5, 7] == pytest.approx(per_mm * scale * 1.5, rel=1e-5)
    with pytest.raises(ValueError, match="sink_table_bgr must be"):
        LightModel(np.zeros((3, 5, 5), np.float32), 0.0, sink_table_bgr=np.zeros((3, 7, 7)))


def test_a_profile_with_the_sink_table_is_format_5_and_reads_back(tmp_path):
    base = default_profile()
    table = (np.arange(3 * base.light.bins**2, dtype=np.float32).reshape(3, base.light.bins, -1) % 17 - 8) / 4
    light = dataclasses.replace(base.light, sink_max_mm=1.5, sink_table_bgr=table)
    assert light.profile_format == 5
    with pytest.raises(ProfileError, match="format 4 with a sink table"):
        save_profile(dataclasses.replace(base, light=light, format=4), tmp_path / "old.toml")
    with pytest.raises(ProfileError, match="format 5 without a sink table"):
        save_profile(dataclasses.replace(base, light=base.light, format=5), tmp_path / "empty.toml")
    profile = dataclasses.replace(base, light=light, format=5)
    back = load_profile(save_profile(profile, tmp_path / "table.toml"))
    assert back.format == 5 and np.array_equal(back.light.sink_table_bgr, table)
    assert back.content_hash() == profile.content_hash()
    plain = dataclasses.replace(profile, light=dataclasses.replace(light, sink_table_bgr=0 * table))
    assert plain.content_hash() != profile.content_hash()
    # the shipped profile (format 2) reads and hashes as runs recorded it
    assert base.content_hash() == "f8edd53ab51690039dfafb1bb1e17db9331b88ef3a7a9f8cc1275dccb8b126ee"
