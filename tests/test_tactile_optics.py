"""The sensor optics and scenes: what changes in a frame, markers, computing only what is needed."""

from pathlib import Path

import numpy as np
import pytest

from rig.sim.contact import Pose
from rig.sim.tactile.optics import SENSOR_KINDS, OpticsSpec, Renderer
from rig.sim.tactile.scene import Scene

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "gelsight_mini"


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
    white = Scene("sphere10mm", "white_markers", optics=OpticsSpec(kind="white_markers", noise_std=0.0)).frame(
        Pose(0, 0, -1.0, 0)).image.astype(int)
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


@pytest.mark.skipif(not SHARED.exists(), reason="real GelSight Mini frames not beside the checkout")
def test_calibrated_optics_explain_the_real_presses():
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
    import calibrate_optics as co

    background, presses = co.load_presses(SHARED)
    _, rms, signal = co.fit(background, presses, 0.5, 9.0)
    assert 1 - rms**2 / signal**2 > 0.6  # the fitted slope model explains most of the real colour change
