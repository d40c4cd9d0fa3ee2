"""The one render call (sensor_sim/press_render.py) and `rig sensor render`: a non-square sensor at its own
resolution, the same frames as the simulated rig's camera and the physics row, and objects too small for
the mechanics grid refused rather than read as no contact."""

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from cli.rig_app import app
from model.conditioning.baseline import ObjectRender
from objects.indenters import sphere
from objects.pose import Pose
from rig.sim.rig_sim import SimulatedRig
from sensor_sim.contact import SensorGeometry, TactileContact, UnresolvedFeature
from sensor_sim.noise import SensorNoise
from sensor_sim.press_render import PressRender, render_press
from sensor_sim.profile import DEFAULT_PROFILE, default_profile, load_profile
from sensor_sim.profile_save import save_profile
from sensor_sim.world_contact import rig_contact

runner = CliRunner()


def wide_profile(tmp_path: Path):
    """The shipped optics on a 320 × 240 sensor over 19.2 × 14.4 mm (0.06 mm/px), without noise."""
    base = default_profile()
    background = cv2.resize(base.background, (640, 480), interpolation=cv2.INTER_LINEAR)  # the camera's own pixels
    wide = dataclasses.replace(
        base,
        name="wide",
        width_px=320,
        height_px=240,
        mm_per_px=0.06,
        background=background,
        noise=SensorNoise((0.0, 0.0, 0.0)),
        format=2,
    )
    return load_profile(save_profile(wide, tmp_path / "wide.toml"))


def test_a_non_square_profile_renders_at_its_own_size_and_place(tmp_path):
    profile = wide_profile(tmp_path)
    press = PressRender(profile, "sphere4mm", "rgb")
    free = press.render(Pose(0.0, 0.0, 0.5, 0.0))
    assert free.shape == (240, 320, 3)
    ys, xs = np.mgrid[0:240, 0:320]
    for x_mm, y_mm in [(6.0, -3.0), (-7.5, 5.0)]:  # the second beyond a square crop of the frame
        col, row = 159.5 + x_mm / 0.06, 119.5 - y_mm / 0.06  # +y is the frame's top
        sink = press.sink_mm(Pose(x_mm, y_mm, -0.6, 0.0))
        deep = np.nonzero(sink > 0.5 * sink.max())
        assert abs(deep[1].mean() - col) < 0.5 and abs(deep[0].mean() - row) < 0.5
        change = np.abs(press.render(Pose(x_mm, y_mm, -0.6, 0.0)).astype(float) - free).sum(axis=2)
        near = np.hypot(xs - col, ys - row) < 30
        assert change[near].mean() > 10 * change[~near].mean()


def test_the_shipped_original_gelsight_is_a_640x480_sensor_whose_light_changes_over_the_field():
    """sensor_sim/data/gelsight_original.toml (bench/calibrate_optics.py --sensor gelsight): the whole frame at
    its own resolution, position terms fitted from presses spread over it, its measured correlated noise."""
    profile = load_profile(DEFAULT_PROFILE.with_name("gelsight_original.toml"))
    assert (profile.width_px, profile.height_px, profile.format) == (640, 480, 2)
    assert profile.light.position_bgr is not None and profile.noise.correlation_px > 0.5
    free = render_press(profile, "sphere4mm", Pose(7.0, 3.0, 0.5, 0.0), noise=False)
    pressed = render_press(profile, "sphere4mm", Pose(7.0, 3.0, -1.5, 0.0), noise=False)
    assert pressed.shape == (480, 640, 3)
    change = np.abs(pressed.astype(float) - free).sum(axis=2)
    assert change[:, 400:].mean() > 20 * change[:, :240].mean()  # the press is right of the centre, and only there


def test_the_rig_camera_the_render_call_and_the_physics_row_give_the_same_frame(tmp_path):
    profile = wide_profile(tmp_path)
    pose = Pose(2.5, 1.0, -0.7, 0.0)
    press = PressRender(profile, "sphere10mm", "rgb")
    with SimulatedRig(profile=profile, indenter="sphere10mm") as sim:
        camera = sim.camera_source()
        rig_frame = camera.renderer.render(sim.world.contact.solve(pose, camera.renderer.needs()).fields)
    assert np.array_equal(press.render(pose), rig_frame)
    physics = ObjectRender("sphere10mm", "rgb", profile, (320, 240), 0.06)
    assert np.array_equal(physics.render([2.5, 1.0, -0.7, 0.0]), rig_frame)


def test_rig_sensor_render_writes_the_frame_and_says_the_wrench(tmp_path):
    profile = wide_profile(tmp_path)
    out = tmp_path / "frame.png"
    result = runner.invoke(
        app,
        ["sensor", "render", "--profile", profile.path, "--object", "sphere4mm", "--pose", "6,-3,-0.6,0"]
        + ["--out", str(out), "--no-noise"],
    )
    assert result.exit_code == 0, result.output
    frame = cv2.imread(str(out), cv2.IMREAD_COLOR)
    assert frame.shape == (240, 320, 3)
    assert np.array_equal(frame, render_press(profile, "sphere4mm", Pose(6.0, -3.0, -0.6, 0.0), noise=False))
    assert "320x240 px over 19.20 x 14.40 mm" in result.output and "in contact; Fz" in result.output
    marked = runner.invoke(
        app,
        ["sensor", "render", "--object", "sphere10mm", "--pose", "0,0,-1,0", "--kind", "rgb_markers"]
        + ["--wrench", "0.5,0,3,0,0,0", "--out", str(tmp_path / "m.png")],
    )
    assert marked.exit_code == 0, marked.output
    assert cv2.imread(str(tmp_path / "m.png")).shape == (256, 256, 3)  # the shipped profile's frame


@pytest.mark.parametrize(
    "args, message",
    [
        (["--object", "sphere4mm", "--pose", "1,2,3"], "--pose: expected 4 values x,y,z,theta"),
        (["--object", "sphere4mm", "--pose", "1,2,nan,0"], "--pose: z is nan"),
        (["--object", "teapot", "--pose", "0,0,-1,0"], "--object 'teapot': unknown indenter 'teapot'"),
        (["--object", "sphere4mm", "--pose", "0,0,-1,0", "--kind", "infrared"], "--kind 'infrared'"),
        (["--object", "sphere4mm", "--pose", "0,0,-1,0", "--wrench", "1,2"], "--wrench: expected 6 values"),
    ],
)
def test_rig_sensor_render_refuses_bad_input_in_one_line(tmp_path, args, message):
    result = runner.invoke(app, ["sensor", "render", *args, "--out", str(tmp_path / "f.png")])
    assert result.exit_code != 0 and message in result.output, result.output
    assert "Traceback" not in result.output and len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "f.png").exists()


def test_an_object_smaller_than_two_cells_is_refused_or_given_a_finer_grid():
    """A 0.1 mm ball on 128 cells over 14 mm (0.109 mm cells) would read Fz = 0, converged: refused,
    naming the cells it needs; the simulated rig's contact refines its grid to them instead."""
    with pytest.raises(UnresolvedFeature, match=r"sphere0.1mm: its smallest feature \(0.1 mm\).*at least 280 cells"):
        TactileContact(sphere(0.1), geometry=SensorGeometry(cells=128))
    refined = rig_contact(sphere(0.1))
    assert refined.solver.geometry.cells == 280
    result = refined.solve(Pose(0.0, 0.0, -0.02, 0.0))
    assert result.converged and result.wrench[2] > 0
    with pytest.raises(UnresolvedFeature, match="at least 28000 cells"):
        rig_contact(sphere(0.001))
    shallow = TactileContact(sphere(10.0), geometry=SensorGeometry(cells=96)).solve(Pose(0.0, 0.0, -1e-4, 0.0))
    assert shallow.wrench[2] == 0 and shallow.sub_cell  # narrower than a cell: said, not silent


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda r: r.render(Pose(float("nan"), 0.0, -0.5, 0.0)), r"pose \(x_mm, y_mm, z_mm, theta_deg\): .*nan"),
        (lambda r: r.render(Pose(0.0, 0.0, float("-inf"), 0.0)), r"pose .*-inf"),
        (lambda r: r.sink_mm(Pose(0.0, 0.0, -0.5, float("inf"))), r"pose .*inf"),
        (lambda r: r.render(Pose(0.0, 0.0, -0.5, 0.0), wrench=[0, 0, float("nan"), 0, 0, 0]), r"wrench .*nan"),
        (lambda r: r.render(Pose(0.0, 0.0, -0.5, 0.0), wrench=[0, 0, 1]), r"wrench .*expected 6 finite numbers"),
        (lambda r: r.pose_at_force(0.0, 0.0, 0.0, float("nan")), r"fz_N: expected 4 finite numbers"),
    ],
)
def test_the_render_call_refuses_a_pose_or_wrench_that_is_not_finite_in_one_line(call, message):
    """A NaN or infinite number reaching the library call is named in one line (it used to fail deep in the
    contact cache with "cannot convert float NaN to integer")."""
    render = PressRender(default_profile(), "sphere10mm", "rgb")
    with pytest.raises(ValueError, match=message) as err:
        call(render)
    assert "\n" not in str(err.value)
