"""The sensor optics and scenes: what changes in a frame, markers, computing only what is needed."""

import csv
import dataclasses
import math
import tomllib
from pathlib import Path

import cv2
import numpy as np
import pytest

from objects.indenters import sphere
from objects.pose import Pose
from sensor_sim.calibration import Press, fit_optics, locate_press, provisional_profile
from sensor_sim.elastomer import Elastomer
from sensor_sim.light import SENSOR_KINDS, LightModel, OpticsSpec, soft_bound
from sensor_sim.noise import SensorNoise
from sensor_sim.optics import Renderer
from sensor_sim.press_render import PressRender
from sensor_sim.profile import ProfileError, default_profile, load_profile
from sensor_sim.profile_save import save_profile
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
    for image, (cx, cy, touch_px) in zip(images[:3], published[:3]):
        found = locate_press(background, Press(image, 2.0), REAL_MM_PER_PX, light)
        # The published circles are hand-drawn and larger than the visibly pressed disc
        # (docs/simulator.md): the contact lies inside them, at a fraction of their radius.
        assert np.hypot(found.centre_x_px - cx, found.centre_y_px - cy) < 0.3 * touch_px
        assert 0.3 * touch_px < found.radius_px < 0.9 * touch_px
        # Moving the press by a known offset moves the contact found by it, to a pixel or two.
        diff = image.astype(np.float32) - background
        moved = np.clip(background + np.roll(diff, (9, -13), axis=(0, 1)), 0, 255).astype(np.uint8)
        again = locate_press(background, Press(moved, 2.0), REAL_MM_PER_PX, light)
        assert abs(again.centre_x_px - (found.centre_x_px - 13)) < 2
        assert abs(again.centre_y_px - (found.centre_y_px + 9)) < 2
        assert abs(again.radius_px - found.radius_px) < 2


@pytest.mark.slow
@pytest.mark.skipif(not SHARED.exists(), reason="real GelSight Mini frames not beside the checkout")
def test_fit_on_four_real_presses_beats_the_background_on_the_fifth():
    background, images, published = _real_presses()
    fit = fit_optics(background, [Press(img, 2.0) for img in images[1:]], REAL_MM_PER_PX)
    contact = locate_press(background, Press(images[0], 2.0), REAL_MM_PER_PX, fit.light)
    render = PressRender(provisional_profile(background, REAL_MM_PER_PX, Elastomer(), fit.light), sphere(4.0))
    rendered = render.render(render.pose_of_pixel(contact.centre_x_px, contact.centre_y_px, -contact.depth_mm))
    ys, xs = np.mgrid[0 : background.shape[0], 0 : background.shape[1]]
    cx, cy, touch_px = published[0]
    near = np.hypot(xs - cx, ys - cy) < 1.5 * touch_px
    real = images[0].astype(np.float32)
    err, err_bg = np.abs(rendered - real), np.abs(background - real)
    assert err.mean() < err_bg.mean()
    assert err[near].mean() < 0.35 * err_bg[near].mean()


def _positional(profile, fmt: int = 2):
    """``profile`` with position and sink terms and correlated noise (format 2 in full; format 3: the
    sink held at 1.2 mm besides)."""
    light = profile.light
    turn = np.stack([np.stack([0.2 * light.table_bgr[c], -0.1 * light.table_bgr[c]]) for c in range(3)])
    positional = LightModel(
        light.table_bgr,
        light.blur_mm,
        light.shading,
        light.reference_bgr,
        position_bgr=turn,
        sink_bgr=np.array([[5.0, 1.0, -1.0], [-3.0, 0.0, 2.0], [8.0, -2.0, 0.0]], np.float32),
        position_scale_mm=7.0,
        position_range=(-0.8, 0.9, -0.7, 0.6),
        sink_max_mm=1.2 if fmt >= 3 else math.inf,
    )
    noise = SensorNoise((1.1, 0.7, 0.9), 0.8, (0.3, -0.1, 0.2))
    return dataclasses.replace(profile, light=positional, noise=noise, format=fmt)


@pytest.mark.parametrize("full", [False, 2, 3], ids=["shipped", "position-sink-noise", "format-3-sink-held"])
def test_profile_round_trips(tmp_path, full):
    profile = _positional(default_profile(), full) if full else default_profile()
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
        "noise",
        "marker_pitch_mm",
        "marker_radius_mm",
        "marker_darkness",
        "format",
    ):
        assert getattr(again, key) == getattr(profile, key), key
    assert np.array_equal(again.background, profile.background)
    light, back = profile.light, again.light
    assert np.abs(back.table_bgr - light.table_bgr).max() <= 5e-4  # written to 3 decimals
    assert back.blur_mm == light.blur_mm and back.shading == light.shading
    if full:
        assert np.abs(back.position_bgr - light.position_bgr).max() <= 6e-4  # 3 decimals, float32
        assert np.array_equal(back.sink_bgr, light.sink_bgr) and back.position_range == light.position_range
        assert back.sink_max_mm == light.sink_max_mm  # 1.2 (format 3) or inf (format 2: never held)
    assert again.content_hash() == load_profile(save_profile(again, tmp_path / "copy.toml")).content_hash()
    frame = Renderer.from_profile(again, "rgb_markers").render({})
    assert frame.shape == (again.height_px, again.width_px, 3)


def test_a_profile_written_before_the_position_dependent_light_still_loads_and_renders_as_before():
    """Format 1 (no format key, one table, noise_std): read as what it says, its content hash
    unchanged (runs recorded with it find it), independent noise at the frame's pixels."""
    old = load_profile(Path(__file__).resolve().parents[1] / "sensor_sim" / "data" / "gelsight_mini_format1.toml")
    assert old.format == 1 and not old.light.extended and old.noise.independent
    assert old.content_hash() == "ea04d248cdaf4778f948c874106fc5672f2d42207e80e8d805c58273fbb7ae32"


@pytest.mark.parametrize(
    "edit, message",
    [
        (("format = 2", "format = 6"), r"\[sensor\] format 6: this version reads profile formats 1, 2, 3, 4, 5"),
        (
            ("position_order = 1", "position_order = 2"),
            r"\[optics\] position_order must be a finite number in \[0, 1\]",
        ),
        (("sink_bgr = ", "# sink_bgr = "), r"missing key \[optics\] sink_bgr"),
        (("correlation_px = ", "correlation_px = -1 #"), r"\[noise\] correlation_px must be a finite number"),
        (
            ("channel_correlation = [", "channel_correlation = [0.99, 0.99, -0.99, "),
            r"\[noise\] channel_correlation must be 3",
        ),
    ],
)
def test_a_format_2_profile_refuses_bad_values_with_one_line(tmp_path, edit, message):
    _refused_after(save_profile(_positional(default_profile()), tmp_path / "mine.toml"), edit, message)


@pytest.mark.parametrize(
    "edit, message",
    [
        (("sink_max_mm = ", "# sink_max_mm = "), r"missing key \[optics\] sink_max_mm"),
        (("sink_max_mm = ", "sink_max_mm = -1 #"), r"\[optics\] sink_max_mm must be a finite number in"),
    ],
)
def test_a_format_3_profile_needs_its_sink_hold_and_format_2_cannot_hold_it(tmp_path, edit, message):
    _refused_after(save_profile(_positional(default_profile(), 3), tmp_path / "mine.toml"), edit, message)
    with pytest.raises(ProfileError, match="format 2 holds no sink_max_mm"):
        save_profile(dataclasses.replace(_positional(default_profile(), 3), format=2), tmp_path / "two.toml")


def test_the_sink_terms_are_held_at_the_deepest_sink_the_light_was_fitted_on():
    """Deeper than ``sink_max_mm`` the sink's change stays at its value there (a change per mm fitted on
    0.2 mm presses is not carried to a 0.8 mm one); without it (inf, format 2) it grows with the sink."""
    light = _positional(default_profile(), 3).light
    open_light = dataclasses.replace(light, sink_max_mm=math.inf)
    flat = np.zeros((8, 8), np.float32)
    background = np.full((8, 8, 3), 100.0, np.float32)

    def change(model, sink_mm):
        planes = model.frame_planes(background, 7.0, 7.0)
        return model.change_frame(flat, flat, np.full((8, 8), sink_mm, np.float32), planes)

    assert np.array_equal(change(light, 0.8), change(open_light, 0.8))  # within the fitted sinks: the same
    assert np.array_equal(change(light, 3.0), change(light, 1.2))
    assert np.abs(change(open_light, 3.0) - change(light, 3.0)).max() > 5.0
    with pytest.raises(ValueError, match="sink_max_mm must be > 0"):
        dataclasses.replace(light, sink_max_mm=float("nan"))


def _refused_after(path: Path, edit: tuple[str, str], message: str) -> None:
    """``path`` with ``edit`` (old, new) made to its text is refused in one line naming it and ``message``."""
    text = path.read_text()
    assert edit[0] in text
    path.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(ProfileError, match=message) as info:
        load_profile(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


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
    _refused_after(save_profile(default_profile(), tmp_path / "mine.toml"), edit, message)


def test_colour_lookup_is_the_same_float32_result_as_the_stacked_bilinear_table(monkeypatch):
    """``LightModel.change`` gathers per corner for speed; it must equal the plain
    formula (stack the four corners, weight, sum) bit for bit, shading included. Through
    ``cv2.remap`` (where this OpenCV interpolates exactly) it is the same to float32 rounding."""
    import sensor_sim.light as light_module
    from sensor_sim.light_tables import normal_lookup

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
