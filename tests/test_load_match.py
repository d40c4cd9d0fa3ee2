"""The tangential state from a measured load (sensor_sim/load_match.py), and the marker render
that uses it (model/conditioning/baseline.py's ObjectRender.render with a wrench)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from objects.indenters import get_indenter
from objects.pose import Pose
from sensor_sim.contact import SensorGeometry, TactileContact
from sensor_sim.load_match import FORCE_TOL_N, MOMENT_TOL_NMM, SLIP_MARGIN, contact_at_load


def _solver(obj: str = "sphere10mm") -> TactileContact:
    return TactileContact(get_indenter(obj), geometry=SensorGeometry(cells=64), tangential_tol=1e-4)


@pytest.mark.parametrize(
    "obj,shift_mm,twist_deg",
    [("sphere10mm", (0.05, -0.02), 0.0), ("square", (0.03, 0.04), 1.5), ("sphere10mm", (0.3, 0.0), 0.0)],
)
def test_the_load_of_a_forward_solve_gives_back_its_state(obj, shift_mm, twist_deg):
    """A solve with a known stick motion (small: sticking; 0.3 mm: well into partial slip) gives a
    load; matching that load finds a state carrying it whose surface displacement is the forward one's."""
    solver = _solver(obj)
    pose = Pose(0.2, -0.1, -0.8, 0.0)
    forward = solver.solve(pose, shift_mm=shift_mm, twist_rad=math.radians(twist_deg), fields={"uxy"})
    load = forward.wrench[[0, 1, 5]]
    assert np.abs(load[:2]).max() > 0.05  # a load worth matching
    match = contact_at_load(solver, pose, load, {"uxy"})
    assert match.matched and not match.scaled
    assert np.abs(match.error[:2]).max() <= FORCE_TOL_N and abs(match.error[2]) <= MOMENT_TOL_NMM
    assert match.shift_mm == pytest.approx(shift_mm, abs=0.01)
    assert math.degrees(match.twist_rad) == pytest.approx(twist_deg, abs=0.1)
    u_fwd = np.hypot(forward.fields["ux"], forward.fields["uy"])
    u_new = np.hypot(match.result.fields["ux"], match.result.fields["uy"])
    assert np.abs(u_new - u_fwd).max() <= 0.05 * u_fwd.max()
    # the wrench of the matched state is the forward one's (force, and the moments' lever terms)
    assert match.result.wrench == pytest.approx(forward.wrench, abs=0.06)


def test_no_tangential_load_is_the_pose_alone_and_out_of_contact_is_nothing():
    solver = _solver()
    pose = Pose(0.0, 0.0, -0.6, 0.0)
    match = contact_at_load(solver, pose, (0.0, 0.0, 0.0), {"uxy"})
    assert match.solves == 0 and match.result.tangential is None
    assert not match.result.fields["ux"].any() and not match.result.fields["uy"].any()
    above = contact_at_load(solver, Pose(0.0, 0.0, 0.5, 0.0), (1.0, 0.0, 0.0), {"uxy"})
    assert not above.result.in_contact and above.solves == 0


def test_a_load_beyond_friction_is_matched_at_the_onset_of_slip():
    solver = _solver()
    pose = Pose(0.0, 0.0, -0.6, 0.0)
    fz = solver.solve(pose).normal.force_N
    mu = solver.gel.friction
    match = contact_at_load(solver, pose, (3 * mu * fz, 0.0, 0.0), {"uxy"})
    assert match.scaled
    assert match.target[0] == pytest.approx(SLIP_MARGIN * mu * fz)
    assert match.result.wrench[0] == pytest.approx(SLIP_MARGIN * mu * fz, abs=3 * FORCE_TOL_N)
    assert match.result.tangential.stick_fraction < 0.5  # mostly slipping


def test_non_finite_load_is_refused():
    with pytest.raises(ValueError, match="must be finite"):
        contact_at_load(_solver(), Pose(0, 0, -0.5, 0), (math.nan, 0, 0))


def test_the_marker_render_follows_the_measured_shear():
    """Markers move with Fx: the render under +Fx differs from the unloaded one, its markers (dark
    blobs) shifted towards +x (image columns grow with x), and -Fx about mirrors it."""
    from model.conditioning.baseline import ObjectRender
    from sensor_sim.profile import default_profile

    render = ObjectRender("sphere10mm", "white_markers", default_profile(), 128, 14 / 128)
    pose = np.array([0.0, 0.0, -1.0, 0.0])
    still = render.render(pose).astype(float)
    assert np.array_equal(render.render(pose, np.zeros(6)), render.render(pose))

    def centroid_shift(img):
        """Mean x shift of the dark marker pixels near the contact against the unloaded render."""
        grey_still, grey = still.mean(axis=2), img.astype(float).mean(axis=2)
        win = slice(40, 88)
        cols = np.arange(128)[None, :]

        def cx(g):
            w = np.clip(200 - g[win, win], 0, None)
            return float((w * cols[:, win]).sum() / w.sum())

        return cx(grey) - cx(grey_still)

    right = render.render(pose, np.array([1.0, 0, 0, 0, 0, 0]))
    left = render.render(pose, np.array([-1.0, 0, 0, 0, 0, 0]))
    assert np.abs(right.astype(float) - still).mean() > 0.5
    assert centroid_shift(right) > 0.05
    # the marker grid is not symmetric in the window: mirrored to within 15 %
    assert centroid_shift(left) == pytest.approx(-centroid_shift(right), rel=0.15)


@pytest.mark.parametrize("depth_mm", [0.3, 1.2, 3.2])  # 3.2: past the 3 mm gel, on the window
def test_depth_for_force_inverts_the_normal_solve(depth_mm):
    from sensor_sim.load_match import depth_for_force

    solver = _solver()
    fz = float(solver.solve(Pose(0.4, 0.1, -depth_mm, 0.0)).wrench[2])
    found = depth_for_force(solver, 0.4, 0.1, 0.0, fz)
    assert float(solver.solve(Pose(0.4, 0.1, -found, 0.0)).wrench[2]) == pytest.approx(fz, abs=FORCE_TOL_N)
    assert found == pytest.approx(depth_mm, abs=0.01)
    assert depth_for_force(solver, 0.4, 0.1, 0.0, 0.0) == 0.0
    for bad in (-1.0, math.inf, math.nan):
        with pytest.raises(ValueError, match="Fz must be"):
            depth_for_force(solver, 0.0, 0.0, 0.0, bad)
