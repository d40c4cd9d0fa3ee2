"""The sensor optics and scenes: what changes in a frame, markers, computing only what is needed."""

import csv
import tomllib
from pathlib import Path

import cv2
import numpy as np
import pytest

from objects.pose import Pose
from sensor_sim.calibration import (
    CalibrationError,
    Contact,
    Press,
    find_contact,
    fit_optics,
    refine_contact,
    render_press,
)
from sensor_sim.light import SENSOR_KINDS, LightModel, OpticsSpec, soft_bound
from sensor_sim.optics import Renderer
from sensor_sim.profile import ProfileError, default_profile, load_profile, save_profile
from sensor_sim.scene import Scene

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "gelsight_mini"
LIBRARY = Path(__file__).resolve().parents[1] / "protocols" / "library"
REAL_MM_PER_PX = 0.0295  # the real frames' scale, as given by their publisher


@pytest.mark.parametrize("kind", SENSOR_KINDS)
def test_frame_changes_only_where_the_gel_is_pressed(kind):
    scene = Scene("sphere4mm", kind, optics=OpticsSpec(kind=kind, noise_std=0.0))
    free = scene.frame(Pose(0, 0, 1.0, 0)).image.astype(float)
    pressed = scene.frame(Pose(2.0, 0, -0.8, 0)).image.astype(float)
    assert free.shape == pressed.shape == (256, 256, 3) and pressed.dtype == np.float64
    diff = np.abs(pressed - free).sum(axis=2)
    ys, xs = np.nonzero(diff > 10)
    assert len(xs) > 100
    mm_per_px = 14.0 / 256
    centre_col = (2.0 / mm_per_px) + 127.5  # +x is to the right
    assert abs(np.median(xs) - centre_col) < 12 and abs(np.median(ys) - 127.5) < 12
    far = np.abs(pressed - free)[:, :40]  # the far left strip: the gel sinks µm there, ±rounding
    assert far.max() <= 2.0


def test_rgb_shows_colour_white_light_does_not():
    rgb = Scene("sphere10mm", "rgb", optics=OpticsSpec(kind="rgb", noise_std=0.0)).frame(Pose(0, 0, -1.0, 0)).image
    white = (
        Scene("sphere10mm", "white_markers", optics=OpticsSpec(kind="white_markers", noise_std=0.0))
        .frame(Pose(0, 0, -1.0, 0))
        .image.astype(int)
    )
    assert np.ptp(rgb.astype(int), axis=2).max() > 60  # strongly coloured lobes
    assert np.abs(white[..., 0] - white[..., 2]).max() <= 1  # grey


def test_markers_move_with_shear_and_only_there():
    renderer = Renderer(OpticsSpec(kind="rgb_markers", noise_std=0.0))
    scene = Scene("sphere10mm", "rgb_markers")
    still = scene.contact.solver.solve(Pose(0, 0, -1.0, 0), fields={"uz", "uxy"})
    sheared = scene.contact.solver.solve(Pose(0.3, 0, -1.0, 0), shift_mm=(0.3, 0.0), fields={"uz", "uxy"})
    rest = renderer.marker_positions_px(still.fields["ux"], still.fields["uy"])
    moved = renderer.marker_positions_px(sheared.fields["ux"], sheared.fields["uy"])
    shift = moved - rest
    near = np.hypot(*(rest - 127.5).T) < 20
    far = np.hypot(*(rest - 127.5).T) > 100
    assert shift[near, 0].mean() > 1.0  # markers under the contact follow +x (pixels)
    assert abs(shift[near, 1].mean()) < 0.3
    assert np.abs(shift[far]).max() < shift[near, 0].mean() / 3  # and decay away from it
    assert len(rest) == 400  # 20 × 20 markers; the metric uses the central 18 × 18


def test_forces_only_scene_computes_no_fields_and_no_render():
    scene = Scene("sphere10mm", "rgb_markers")
    frame = scene.frame(Pose(0, 0, -0.8, 0), image=False)
    assert frame.image is None and frame.contact.fields == {} and scene._renderer is None
    assert frame.contact.tangential is None  # no shear, no twist: no tangential solve


def test_rgb_scene_skips_the_tangential_field():
    scene = Scene("sphere10mm", "rgb")
    frame = scene.frame(Pose(0.2, 0, -0.8, 0))
    assert set(frame.contact.fields) == {"uz"}


def test_image_reuses_the_solve_of_the_same_pose():
    scene = Scene("sphere10mm", "rgb_markers")
    scene.frame(Pose(0, 0, -0.8, 0), image=False)
    scene.frame(Pose(0, 0, -0.8, 0))
    assert scene.contact.solves == 1


def test_unknown_sensor_kind():
    with pytest.raises(ValueError, match="rgb_markers"):
        OpticsSpec(kind="infrared")


def test_supplied_background_is_used():
    bg = np.full((100, 100, 3), 50, np.uint8)
    img = Scene("sphere10mm", "rgb", optics=OpticsSpec(noise_std=0.0), background=bg).frame(Pose(0, 0, 1, 0)).image
    assert np.all(img == 50)


@pytest.mark.parametrize("kind", SENSOR_KINDS)
def test_deepest_press_of_every_library_protocol_has_no_clipped_pixel(kind):
    protocols = sorted(LIBRARY.glob("*.toml"))
    assert len(protocols) >= 10
    for path in protocols:
        protocol = tomllib.loads(path.read_text())
        obj, depth_mm = protocol["protocol"]["object"], protocol["motion"]["max_depth_mm"]
        frame = Scene(obj, kind, optics=OpticsSpec(kind=kind, noise_std=1.0)).frame(Pose(0, 0, -depth_mm, 0))
        sink = cv2.resize(frame.contact.fields["uz"].astype(np.float32), frame.image.shape[1::-1])
        inside = sink > 0.05  # where the gel is pressed in by more than 50 µm
        assert inside.sum() > 1000, f"{obj}: no contact at {depth_mm} mm"
        clipped = ((frame.image == 0) | (frame.image == 255)).any(axis=2)
        assert not clipped[inside].any(), f"{obj} {kind} at {depth_mm} mm: {clipped[inside].sum()} clipped pixels"
        assert np.isfinite(frame.contact.fields["uz"]).all()


def test_colour_is_bounded_for_any_slope():
    light = default_profile().light
    background = np.full((64, 64, 3), 240.0, np.float32)  # bright: the worst case for saturation
    rng = np.random.default_rng(1)
    gx, gy = (rng.normal(0, 1, (64, 64)).astype(np.float32) * 10.0 ** rng.uniform(-3, 4, (64, 64)) for _ in range(2))
    change = light.change(gx, gy, background)
    assert np.isfinite(change).all()
    bound = np.abs(light.table_bgr).max() * (background / np.asarray(light.reference_bgr)).max()
    assert np.abs(change).max() <= bound + 1e-3
    framed = soft_bound(background + change)
    assert framed.min() >= 1.0 and framed.max() <= 254.0
    middle = np.linspace(20, 230, 50)
    assert np.array_equal(soft_bound(middle), middle)  # ordinary values are untouched


def _lambertian_light(bins: int = 21) -> LightModel:
    """A known model: three coloured lights from the sides (the change from the flat gel's colour)."""
    n = np.linspace(-1, 1, bins)
    nx, ny = np.meshgrid(n, n)
    nz = np.sqrt(np.clip(1 - nx**2 - ny**2, 0, 1))
    lights = np.array([[0.7, 0.0, 0.7], [-0.35, 0.6, 0.7], [-0.35, -0.6, 0.7]])  # one per channel, B G R
    shade = np.stack([np.maximum(0, d[0] * nx + d[1] * ny + d[2] * nz) - d[2] for d in lights])
    return LightModel((90.0 * shade).astype(np.float32), 0.1, "multiplicative", (100.0, 100.0, 100.0))


def test_calibration_recovers_a_known_model():
    truth = _lambertian_light()
    h, w, mm_per_px, ball_mm = 240, 320, 0.03, 2.0
    ys, xs = np.mgrid[0:h, 0:w]
    background = np.stack([80 + 40 * xs / w, 110 - 20 * ys / h, 90 + 30 * (xs + ys) / (w + h)], axis=-1).astype(
        np.float32
    )
    rng = np.random.default_rng(0)
    contacts = [
        Contact(90.3, 80.6, 22.0),
        Contact(220.8, 150.2, 30.0),
        Contact(160.0, 120.0, 26.0),
        Contact(100.4, 170.7, 34.0),
    ]
    presses = [
        Press(
            np.clip(
                render_press(truth, background, c, ball_mm, mm_per_px) + rng.normal(0, 1.0, background.shape), 0, 255
            ).astype(np.uint8),
            ball_mm,
        )
        for c in contacts
    ]
    fit = fit_optics(background.astype(np.uint8), presses, mm_per_px)
    for found, true in zip(fit.contacts, contacts):
        assert abs(found.centre_x_px - true.centre_x_px) < 1.0 and abs(found.centre_y_px - true.centre_y_px) < 1.0
        assert abs(found.radius_px - true.radius_px) < 1.5
    unseen = Contact(250.0, 70.0, 28.0)  # a press the fit never saw, at another place
    real = render_press(truth, background, unseen, ball_mm, mm_per_px)
    rendered = render_press(fit.light, background, unseen, ball_mm, mm_per_px)
    signal = np.abs(real - background).mean()
    assert np.abs(rendered - real).mean() < 0.05 * signal  # table, blur and contacts all recovered


def test_calibration_refuses_a_frame_without_contact():
    background = np.full((120, 160, 3), 100, np.uint8)
    with pytest.raises(CalibrationError, match="no contact visible"):
        fit_optics(background, [Press(background.copy(), 2.0)], 0.03)
    with pytest.raises(CalibrationError, match="press 0: frame is"):
        fit_optics(background, [Press(background[:60], 2.0)], 0.03)


def _real_presses():
    background = cv2.imread(str(SHARED / "background.png"), cv2.IMREAD_COLOR)
    rows = list(csv.DictReader(open(SHARED / "presses.csv")))
    images = [cv2.imread(str(SHARED / r["file"]), cv2.IMREAD_COLOR) for r in rows]
    published = [
        (float(r["touch_center_x_px"]), float(r["touch_center_y_px"]), float(r["touch_radius_px"])) for r in rows
    ]
    return background, images, published


@pytest.mark.skipif(not SHARED.exists(), reason="real GelSight Mini frames not beside the checkout")
def test_contacts_found_on_the_real_presses():
    background, images, published = _real_presses()
    light = default_profile().light
    for image, (cx, cy, touch_px) in zip(images, published):
        press = Press(image, 2.0)
        found = refine_contact(light, background, press, find_contact(background, image), REAL_MM_PER_PX)
        # The published circles are hand-drawn and larger than the visibly pressed disc
        # (docs/simulator.md): the contact lies inside them, at a fraction of their radius.
        assert np.hypot(found.centre_x_px - cx, found.centre_y_px - cy) < 0.3 * touch_px
        assert 0.4 * touch_px < found.radius_px < 0.9 * touch_px
        # Moving the press by a known offset moves the contact found by it, to a pixel or two.
        diff = image.astype(np.float32) - background
        moved = np.clip(background + np.roll(diff, (9, -13), axis=(0, 1)), 0, 255).astype(np.uint8)
        again = refine_contact(light, background, Press(moved, 2.0), find_contact(background, moved), REAL_MM_PER_PX)
        assert abs(again.centre_x_px - (found.centre_x_px - 13)) < 2
        assert abs(again.centre_y_px - (found.centre_y_px + 9)) < 2
        assert abs(again.radius_px - found.radius_px) < 2


@pytest.mark.slow
@pytest.mark.skipif(not SHARED.exists(), reason="real GelSight Mini frames not beside the checkout")
def test_fit_on_four_real_presses_beats_the_background_on_the_fifth():
    background, images, published = _real_presses()
    fit = fit_optics(background, [Press(img, 2.0) for img in images[1:]], REAL_MM_PER_PX)
    press = Press(images[0], 2.0)
    contact = refine_contact(fit.light, background, press, find_contact(background, images[0]), REAL_MM_PER_PX)
    rendered = np.clip(render_press(fit.light, background, contact, 2.0, REAL_MM_PER_PX), 0, 255)
    ys, xs = np.mgrid[0 : background.shape[0], 0 : background.shape[1]]
    cx, cy, touch_px = published[0]
    near = np.hypot(xs - cx, ys - cy) < 1.5 * touch_px
    real = images[0].astype(np.float32)
    err, err_bg = np.abs(rendered - real), np.abs(background - real)
    assert err.mean() < err_bg.mean()
    assert err[near].mean() < 0.35 * err_bg[near].mean()


def test_profile_round_trips(tmp_path):
    profile = default_profile()
    path = save_profile(profile, tmp_path / "mine.toml")
    assert (tmp_path / "mine.png").exists()
    again = load_profile(path)
    for key in (
        "name",
        "width_px",
        "height_px",
        "mm_per_px",
        "gel_thickness_mm",
        "gel_E_MPa",
        "noise_std",
        "marker_pitch_mm",
        "marker_radius_mm",
        "marker_darkness",
    ):
        assert getattr(again, key) == getattr(profile, key), key
    assert np.array_equal(again.background, profile.background)
    assert np.abs(again.light.table_bgr - profile.light.table_bgr).max() <= 5e-4  # written to 3 decimals
    assert again.light.blur_mm == profile.light.blur_mm and again.light.shading == profile.light.shading
    frame = Renderer.from_profile(again, "rgb_markers").render({})
    assert frame.shape == (again.height_px, again.width_px, 3)


@pytest.mark.parametrize(
    "edit, message",
    [
        (("blur_mm = ", "blur_mm = nan #"), r"\[optics\] blur_mm must be a finite number"),
        (("E_MPa = ", "E_MPa = inf #"), r"\[gel\] E_MPa must be a finite number"),
        (("width_px = 256", "width_px = -3"), r"\[sensor\] width_px must be a finite number"),
        (("thickness_mm = ", "# thickness_mm = "), r"missing key \[gel\] thickness_mm"),
        (("table_bins = 21", "table_bins = 19"), r"\[optics\] table_b must be 19×19"),
        (('shading = "multiplicative"', 'shading = "glossy"'), r"\[optics\] shading must be one of"),
        (('background = "mine.png"', 'background = "absent.png"'), r"\[sensor\] background 'absent.png'"),
    ],
)
def test_profile_refuses_bad_values_with_one_line(tmp_path, edit, message):
    path = save_profile(default_profile(), tmp_path / "mine.toml")
    text = path.read_text()
    assert edit[0] in text
    path.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(ProfileError, match=message) as info:
        load_profile(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_colour_lookup_is_the_same_float32_result_as_the_stacked_bilinear_table(monkeypatch):
    """``LightModel.change`` gathers per corner for speed; it must equal the plain
    formula (stack the four corners, weight, sum) bit for bit, shading included. Through
    ``cv2.remap`` (where this OpenCV interpolates exactly) it is the same to float32 rounding."""
    import sensor_sim.light as light_module
    from sensor_sim.light import normal_lookup

    light = default_profile().light
    rng = np.random.default_rng(7)
    gx, gy = (rng.normal(0, 0.4, (96, 80)).astype(np.float32) for _ in range(2))
    gx[:20], gy[:20] = 0.0, 0.0  # the flat gel too
    background = rng.uniform(30, 240, (96, 80, 3)).astype(np.float32)
    idx, w = normal_lookup(gx, gy, light.bins)
    flat = light.table_bgr.reshape(3, -1)
    expected = np.stack([(flat[ch][idx] * w).sum(axis=-1) for ch in range(3)], axis=-1)
    if light.shading == "multiplicative":
        expected *= background / np.asarray(light.reference_bgr, dtype=np.float32)
    if light_module.remap_interpolates_exactly():
        remapped = light.change(gx, gy, background)
        assert np.abs(remapped - expected).max() < 1e-3 and not np.array_equal(remapped, 0 * expected)
    monkeypatch.setattr(light_module, "remap_interpolates_exactly", lambda: False)
    assert np.array_equal(light.change(gx, gy, background), expected)
