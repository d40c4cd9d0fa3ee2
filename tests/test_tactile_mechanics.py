"""Contact mechanics against closed forms, on stiff and extreme cases, and for consistency."""

import logging
import math

import numpy as np
import pytest

from objects.indenters import INDENTERS, get_indenter
from objects.pose import Pose
from sensor_sim.backing import WINDOW_E_STAR_MPa
from sensor_sim.contact import SensorGeometry, TactileContact
from sensor_sim.elastomer import Elastomer, PhysicsInputError
from sensor_sim.kernels import Kernels, cell_integrals, layer_factor
from sensor_sim.light import OpticsSpec
from sensor_sim.normal_contact import solve_normal
from sensor_sim.scene import Scene
from sensor_sim.tangential_contact import solve_tangential
from sensor_sim.world_contact import ElastomerContact

HALF_SPACE = Elastomer(E_MPa=1.0, nu=0.5, thickness_mm=math.inf, friction=0.5)


def grid(n, extent_mm):
    dx = extent_mm / n
    x = (np.arange(n) - (n - 1) / 2) * dx
    X, Y = np.meshgrid(x, x)
    return X, Y, dx


def hertz(R, d, gel=HALF_SPACE):
    a = math.sqrt(R * d)
    F = 4 / 3 * gel.E_star_MPa * math.sqrt(R) * d**1.5
    return F, a, 3 * F / (2 * math.pi * a * a)


def test_cell_integrals_match_quadrature():
    I1, Ixx, Iyy, Ixy = cell_integrals(6, 6, 0.5, 0.5)
    assert I1[0, 0] == pytest.approx(4 * 0.5 * math.asinh(1.0))  # ∬ 1/r over a square about its centre
    s = (np.arange(300) + 0.5) / 300 * 0.5 - 0.25
    for iy, ix in [(0, 2), (1, 3), (11, 10)]:
        X = (ix if ix < 6 else ix - 12) * 0.5
        Y = (iy if iy < 6 else iy - 12) * 0.5
        xx, yy = np.meshgrid(X - s, Y - s)
        r = np.hypot(xx, yy)
        area = 0.25
        assert I1[iy, ix] == pytest.approx((1 / r).mean() * area, rel=1e-4)
        assert Ixx[iy, ix] == pytest.approx((xx**2 / r**3).mean() * area, rel=1e-4)
        assert Ixy[iy, ix] == pytest.approx((xx * yy / r**3).mean() * area, rel=1e-4, abs=1e-9)


def test_layer_factor_limits():
    assert layer_factor(np.array([50.0]), 0.3)[0] == pytest.approx(1.0)  # thick: half-space
    qh, nu = 1e-3, 0.3
    assert layer_factor(np.array([qh]), nu)[0] == pytest.approx(qh * (1 - 2 * nu) / (2 * (1 - nu) ** 2), rel=1e-3)
    assert layer_factor(np.array([1e-3]), 0.5)[0] == pytest.approx(0.0, abs=1e-6)  # incompressible thin layer


def test_thin_layer_is_oedometric():
    """A uniform pressure on a thin bonded layer sinks it by h·p/M, M the oedometric modulus."""
    gel = Elastomer(E_MPa=1.0, nu=0.3, thickness_mm=0.5)
    k = Kernels(64, 64, 0.1, gel)  # a 6.4 mm pad, 13 thicknesses wide
    u = k.normal_displacement(np.ones((64, 64)))
    M = gel.E_MPa * (1 - gel.nu) / ((1 + gel.nu) * (1 - 2 * gel.nu))
    assert u[32, 32] == pytest.approx(0.5 / M, rel=0.01)
    assert u[0, 0] == pytest.approx(u[32, 32] / 2, rel=0.25)  # a corner carries about half


def test_thick_layer_tends_to_the_half_space():
    R, d = 5.0, 0.2
    F, a, _ = hertz(R, d)
    X, Y, dx = grid(64, 3 * a)
    thick = Elastomer(E_MPa=1.0, nu=0.5, thickness_mm=200.0)
    s = solve_normal(Kernels(64, 64, dx, thick), (X**2 + Y**2) / (2 * R), d, tol=1e-5)
    assert s.force_N == pytest.approx(F, rel=0.01)
    thin = Elastomer(E_MPa=1.0, nu=0.5, thickness_mm=1.0)
    s_thin = solve_normal(Kernels(64, 64, dx, thin), (X**2 + Y**2) / (2 * R), d, tol=1e-5)
    assert s_thin.force_N > 1.2 * F  # a layer as thin as the contact is much stiffer


@pytest.mark.parametrize("n", [64, 128])
def test_hertz_force_radius_and_peak_pressure(n):
    R, d = 5.0, 0.2
    F, a, p0 = hertz(R, d)
    X, Y, dx = grid(n, 3 * a)
    s = solve_normal(Kernels(n, n, dx, HALF_SPACE), (X**2 + Y**2) / (2 * R), d, tol=1e-4)
    assert s.converged
    assert s.force_N == pytest.approx(F, rel=0.01)
    assert math.sqrt(s.contact_area_mm2 / math.pi) == pytest.approx(a, rel=0.02)
    assert s.pressure_MPa.max() == pytest.approx(p0, rel=0.02)


def test_sphere_force_exponent_and_radius_scaling():
    tc = TactileContact(
        get_indenter("sphere10mm"),
        Elastomer(E_MPa=0.3, nu=0.49, thickness_mm=math.inf),
        SensorGeometry(width_mm=10, height_mm=10, cells=128),
        tol=1e-5,
    )
    depths = np.array([0.1, 0.2, 0.3, 0.4])
    sols = [tc.solve(Pose(0, 0, -d, 0)).normal for d in depths]
    F = np.array([s.force_N for s in sols])
    a = np.sqrt(np.array([s.contact_area_mm2 for s in sols]) / math.pi)
    assert np.polyfit(np.log(depths), np.log(F), 1)[0] == pytest.approx(1.5, abs=0.05)
    assert np.polyfit(np.log(depths), np.log(a), 1)[0] == pytest.approx(0.5, abs=0.05)


def test_flat_punch_force():
    a, d = 1.0, 0.05
    X, Y, dx = grid(128, 2.4 * a)
    h = np.where(np.hypot(X, Y) <= a, 0.0, 50.0)
    s = solve_normal(Kernels(128, 128, dx, HALF_SPACE), h, d, tol=1e-5)
    assert s.converged
    assert s.force_N == pytest.approx(2 * a * HALF_SPACE.E_star_MPa * d, rel=0.02)


@pytest.mark.parametrize("ratio", [0.3, 0.7, 0.95])
def test_cattaneo_mindlin_partial_slip(ratio):
    R, d, n = 5.0, 0.2, 64
    _, a, _ = hertz(R, d)
    X, Y, dx = grid(n, 2.6 * a)
    k = Kernels(n, n, dx, HALF_SPACE)
    normal = solve_normal(k, (X**2 + Y**2) / (2 * R), d, tol=1e-6)
    P, mu, G, nu = normal.force_N, HALF_SPACE.friction, HALF_SPACE.G_MPa, HALF_SPACE.nu
    delta = 3 * mu * P * (2 - nu) / (16 * G * a) * (1 - (1 - ratio) ** (2 / 3))
    t = solve_tangential(k, normal.pressure_MPa, X, Y, mu=mu, shift_mm=(delta, 0.0), tol=1e-5)
    assert t.converged
    assert t.fx_N == pytest.approx(ratio * mu * P, rel=0.01)
    stick_radius = math.sqrt(t.stick_fraction * normal.contact_area_mm2 / math.pi)
    assert stick_radius == pytest.approx(a * (1 - ratio) ** (1 / 3), abs=2 * dx)
    assert abs(t.fy_N) < 1e-6 * P


def test_full_slip_and_45_degree_twist():
    R, d, n = 5.0, 0.2, 64
    _, a, _ = hertz(R, d)
    X, Y, dx = grid(n, 2.6 * a)
    k = Kernels(n, n, dx, HALF_SPACE)
    normal = solve_normal(k, (X**2 + Y**2) / (2 * R), d, tol=1e-6)
    P, mu = normal.force_N, HALF_SPACE.friction
    slide = solve_tangential(k, normal.pressure_MPa, X, Y, mu=mu, shift_mm=(0.0, -3.0))
    assert slide.fy_N == pytest.approx(-mu * P, rel=1e-3) and slide.stick_fraction == 0.0
    twist = solve_tangential(k, normal.pressure_MPa, X, Y, mu=mu, twist_rad=math.radians(45))
    assert twist.mz_Nmm == pytest.approx(3 * math.pi / 16 * mu * P * a, rel=0.01)  # torsional full slip


GEL = Elastomer()


@pytest.mark.parametrize("E_MPa", [0.05, 1.0, 2e5])  # 0.05 MPa gel to 200 GPa steel
def test_stiffness_range_is_finite_and_linear_in_modulus(E_MPa):
    tc = TactileContact(get_indenter("sphere10mm"), Elastomer(E_MPa=E_MPa, nu=0.45, thickness_mm=3.0))
    r = tc.solve(Pose(0, 0, -0.4, 0), shift_mm=(0.1, 0.0), twist_rad=0.01)
    ref = TactileContact(get_indenter("sphere10mm"), Elastomer(E_MPa=1.0, nu=0.45, thickness_mm=3.0)).solve(
        Pose(0, 0, -0.4, 0)
    )
    assert np.all(np.isfinite(r.wrench)) and r.normal.converged and r.tangential.converged
    assert r.wrench[2] == pytest.approx(ref.wrench[2] * E_MPa, rel=1e-3)


@pytest.mark.parametrize("name", sorted(INDENTERS))
def test_every_indenter_force_monotone_in_depth_and_converged(name):
    tc = TactileContact(get_indenter(name), GEL)
    forces = []
    for depth in (0.1, 0.4, 0.8, 1.6, 2.9):  # up to just short of the 3 mm gel
        r = tc.solve(Pose(0.0, 0.0, -depth, 15.0))
        assert np.all(np.isfinite(r.wrench)) and r.normal.converged, (name, depth, r.normal.residual)
        forces.append(r.wrench[2])
    assert all(b > a for a, b in zip(forces, forces[1:])), (name, forces)


def test_no_contact_and_near_miss_are_zero():
    tc = TactileContact(get_indenter("sphere10mm"), GEL)
    for pose in (Pose(0, 0, 2.0, 0), Pose(0, 0, 0.0, 0), Pose(20.0, 0, -1.0, 0)):  # above, touching, off the pad
        r = tc.solve(pose, shift_mm=(0.5, 0), fields={"uz", "uxy"})
        assert np.all(r.wrench == 0) and not r.in_contact
        assert not r.fields["uz"].any() and not r.fields["ux"].any()


def test_indenter_larger_than_sensor():
    r = TactileContact(get_indenter("woven"), GEL).solve(Pose(0, 0, -0.5, 0), fields={"uz"})
    assert r.normal.converged and np.all(np.isfinite(r.fields["uz"]))
    assert r.normal.contact.mean() > 0.3  # the board touches across the whole pad


def test_shear_beyond_friction_is_full_slip_and_reverses():
    tc = TactileContact(get_indenter("sphere10mm"), GEL)
    # Slip starts at δ* = 3μP(2−ν)/(16Ga) ≈ 3 mm on this soft gel: slide 5 mm.
    fwd = tc.solve(Pose(0.0, 0, -0.8, 0), shift_mm=(5.0, 0.0))
    back = tc.solve(Pose(0.0, 0, -0.8, 0), shift_mm=(-5.0, 0.0))
    assert fwd.wrench[0] == pytest.approx(GEL.friction * fwd.wrench[2], rel=1e-3)
    assert back.wrench[0] == pytest.approx(-GEL.friction * back.wrench[2], rel=1e-3)
    assert fwd.tangential.stick_fraction == 0.0


def test_twist_produces_mz_with_the_sign_of_the_twist():
    tc = TactileContact(get_indenter("square"), GEL)
    plus = tc.solve(Pose(0, 0, -0.4, 5.0), twist_rad=math.radians(5.0))
    minus = tc.solve(Pose(0, 0, -0.4, -5.0), twist_rad=math.radians(-5.0))
    assert plus.wrench[5] > 0 > minus.wrench[5]
    assert plus.wrench[5] == pytest.approx(-minus.wrench[5], rel=1e-2)


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda: Elastomer(E_MPa=-1.0), "E_MPa"),
        (lambda: Elastomer(E_MPa=float("nan")), "E_MPa"),
        (lambda: Elastomer(nu=0.6), "Poisson"),
        (lambda: Elastomer(thickness_mm=0.0), "thickness"),
        (lambda: Elastomer(friction=-0.1), "friction"),
        (lambda: TactileContact(get_indenter("sphere10mm"), GEL).solve(Pose(float("nan"), 0, -1.0, 0)), "finite"),
    ],
)
def test_meaningless_inputs_are_clear_errors(make, words):
    with pytest.raises(PhysicsInputError, match=words):
        make()


def test_unknown_indenter_names_the_choices():
    with pytest.raises(KeyError, match="sphere10mm"):
        get_indenter("teapot")


# --- Consistency at the rigid window and of the solvers' reports ---


@pytest.mark.parametrize("name", ["sphere10mm", "circle8mm"])
def test_force_is_continuous_and_monotonic_through_the_gel_thickness(name):
    """No jump at d = thickness: the window adds a steep but finite contact stiffness."""
    contact = ElastomerContact(name)  # the gauge's model, as the simulated rig uses it
    step_mm = 0.5e-3  # the gauge model's pose quantum
    depths = GEL.thickness_mm + np.arange(-6, 21) * step_mm
    results = [contact.solve(Pose(0.0, 0.0, -d, 0.0)) for d in depths]
    fz = np.array([r.wrench[2] for r in results])
    assert np.all(np.isfinite(fz)) and all(r.converged for r in results)
    assert np.all(np.diff(fz) >= 0) and fz[-1] > fz[0]
    gel_step_N = np.diff(fz[:7]).max()  # the gel's own rise per step, up to the thickness
    for before, after, r in zip(fz, fz[1:], results[1:]):
        # At most the gel's rise plus the window's stiffest response: under the whole contact.
        window_N_per_mm = 2 * WINDOW_E_STAR_MPa * math.sqrt(r.normal.contact_area_mm2 / math.pi)
        assert after - before <= 2 * gel_step_N + window_N_per_mm * step_mm, (name, before, after)
    assert not any(r.on_backing for r, d in zip(results, depths) if d <= GEL.thickness_mm)
    assert results[-1].on_backing and results[-1].backing.force_N > 0
    at = 6  # depths[6] is the thickness
    slope_before, slope_past = (fz[at] - fz[0]) / at, (fz[-1] - fz[at]) / (len(fz) - 1 - at)
    assert slope_past > 10 * slope_before  # the window is far stiffer than the gel: the guard trips soon
    assert fz[-1] < 1e3  # 10 µm past the gel: steep, not a saturated 10 kN


def test_image_past_the_thickness_shows_the_fully_squeezed_gel():
    scene = Scene("sphere10mm", "rgb", optics=OpticsSpec(kind="rgb", noise_std=0.0))
    free = scene.frame(Pose(0, 0, 1.0, 0)).image.astype(float)
    near = scene.frame(Pose(0, 0, -2.9, 0))
    past = scene.frame(Pose(0, 0, -3.05, 0))
    uz = past.contact.fields["uz"]
    assert uz.max() == pytest.approx(GEL.thickness_mm, rel=1e-3)  # squeezed to the window, not beyond
    assert past.contact.on_backing and past.wrench[2] > near.wrench[2]
    change_near = np.abs(near.image - free).mean()
    change_past = np.abs(past.image - free).mean()
    assert change_past >= 0.9 * change_near > 1.0  # the pressed gel, not an untouched one


def test_tight_tolerances_switch_to_float64_and_converge():
    R, d, n = 5.0, 0.2, 128
    _, a, _ = hertz(R, d)
    X, Y, dx = grid(n, 3 * a)
    s = solve_normal(Kernels(n, n, dx, HALF_SPACE), (X**2 + Y**2) / (2 * R), d, tol=1e-10)
    assert s.converged and s.float64 and s.residual < 1e-10 and s.iterations < 250


def test_a_tolerance_beyond_reach_stops_early_as_not_converged():
    R, d, n = 5.0, 0.2, 64
    _, a, _ = hertz(R, d)
    X, Y, dx = grid(n, 2.6 * a)
    k = Kernels(n, n, dx, HALF_SPACE)
    normal = solve_normal(k, (X**2 + Y**2) / (2 * R), d, tol=1e-30)
    assert not normal.converged and normal.float64 and normal.iterations < 500  # stalled, not max_iter
    ordinary = solve_normal(k, (X**2 + Y**2) / (2 * R), d, tol=1e-6)
    assert ordinary.converged and not ordinary.float64
    t = solve_tangential(k, ordinary.pressure_MPa, X, Y, mu=0.5, shift_mm=(0.01, 0.0), tol=1e-30)
    assert not t.converged and t.float64 and t.iterations < 2000


def test_unconverged_solves_are_counted_and_warned_once(caplog):
    contact = ElastomerContact("sphere10mm", tol=1e-30)
    with caplog.at_level(logging.WARNING, logger="sensor_sim.world_contact"):
        results = [contact.solve(Pose(0.0, 0.0, -d, 0.0)) for d in (0.3, 0.5, 0.7)]
    assert [r.converged for r in results] == [False] * 3
    assert all(0 < r.normal_iterations < 500 and r.normal_residual > 0 for r in results)
    assert contact.solver_warnings == 3
    warnings = [rec for rec in caplog.records if rec.levelno == logging.WARNING]
    assert len(warnings) == 1 and "did not converge" in warnings[0].getMessage()


def test_ordinary_solves_converge_and_report():
    contact = ElastomerContact("sphere10mm")
    r = contact.solve(Pose(0.2, 0.0, -0.8, 3.0))
    r = contact.solve(Pose(0.4, 0.0, -0.8, 3.0))  # sheared since contact began: a tangential solve
    assert r.converged and r.tangential is not None
    assert r.normal_iterations > 0 and r.tangential_iterations > 0
    assert r.normal_residual < contact.solver.tol and r.tangential_residual < contact.solver.tangential_tol
    assert contact.solver_warnings == 0


def _protocol_like_poses():
    """A press, a shear out and back and a twist at 10 µm (0.04°) a frame: the protocols' steps."""
    poses = [Pose(0.0, 0.0, -z, 0.0) for z in np.arange(1.40, 1.6001, 0.01)]
    poses += [Pose(0.0, y, -1.6, 0.0) for y in np.arange(0.01, 0.6001, 0.01)]
    poses += [Pose(0.0, 0.6 - y, -1.6, 0.0) for y in np.arange(0.01, 0.6001, 0.01)]
    poses += [Pose(0.0, 0.0, -1.6, th) for th in np.arange(0.04, 2.0001, 0.04)]
    return poses


def test_warm_started_rig_solves_stay_within_their_stated_error_of_tight_solves():
    """The simulated rig's solves (tolerance 1e-3, warm-started from the last frames,
    extrapolated along the motion) against the same sequence solved to 1e-6: within
    0.01 N and 0.2 N·mm on every frame (measured: 0.003 N, 0.07 N·mm; gauge noise is 0.004 N)."""
    fast = ElastomerContact("sphere10mm", geometry=SensorGeometry(cells=96))
    tight = ElastomerContact("sphere10mm", geometry=SensorGeometry(cells=96))
    tight.use_tolerance(1e-6)
    poses = _protocol_like_poses()
    w_fast = np.array([fast.solve(p).wrench for p in poses])
    w_tight = np.array([tight.solve(p).wrench for p in poses])
    assert np.abs(w_tight[:, 2]).max() > 5.0 and np.abs(w_tight[:, 1]).max() > 1.0  # a real load, really sheared
    assert np.abs(w_fast[:, :3] - w_tight[:, :3]).max() < 0.01
    assert np.abs(w_fast[:, 3:] - w_tight[:, 3:]).max() < 0.2


def test_extrapolated_warm_start_needs_fewer_iterations_than_the_last_solution_alone():
    poses = _protocol_like_poses()
    extrapolated = ElastomerContact("sphere10mm", geometry=SensorGeometry(cells=96))
    plain = ElastomerContact("sphere10mm", geometry=SensorGeometry(cells=96))
    last_only = plain._warm_start

    def no_trend(motion):
        plain._history = plain._history[-1:]  # one solve remembered: no trend to extrapolate
        return last_only(motion)

    plain._warm_start = no_trend  # type: ignore[method-assign]
    its = {}
    for name, model in (("extrapolated", extrapolated), ("plain", plain)):
        results = [model.solve(p) for p in poses]
        assert all(r.converged for r in results)
        its[name] = sum(r.normal_iterations + r.tangential_iterations for r in results)
    assert its["extrapolated"] < 0.75 * its["plain"]  # measured: about half


def test_a_full_grid_warm_start_is_cut_to_the_moving_crop():
    """A warm start on the full grid lands on the contact wherever its crop is; the old
    behaviour (a crop-sized array from another crop) would be shifted by the crop's move."""
    tc = TactileContact(get_indenter("sphere10mm"), geometry=SensorGeometry(cells=96), tol=1e-6)
    here, there = Pose(0.0, 0.0, -1.0, 0.0), Pose(0.5, 0.3, -1.0, 0.0)
    first = tc.solve(here)
    full = np.zeros(tc.X.shape)
    full[first.crop] = first.normal.pressure_MPa
    moved = tc.solve(there, p0=np.roll(full, (-2, 3), axis=(0, 1)))  # the same contact, 2 rows up and 3 right
    cold = tc.solve(there)
    assert moved.normal.iterations < cold.normal.iterations
    assert moved.wrench[2] == pytest.approx(cold.wrench[2], rel=1e-4)
