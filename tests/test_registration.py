"""The labels' registration (sensor_sim/registration.py): learnt from presses found in their frames,
it moves a new press's labelled centre and radius to where its frame would show the contact."""

import math

import numpy as np
import pytest
from test_calibration import BALL_MM, GEL, MM_PER_PX, background, position_light, pressed

from objects.indenters import sphere
from sensor_sim.calibration import Press, locate_press, provisional_profile
from sensor_sim.press_render import PressRender
from sensor_sim.registration import Registration, RegistrationError, fit_registration


def test_the_median_offset_and_ratio_ignore_one_mislabelled_press_of_four():
    located = [(100.0, 80.0, 20.0), (200.0, 60.0, 25.0), (150.0, 150.0, 22.0), (60.0, 190.0, 21.0)]
    labels = [(x - 3.0, y + 2.0, r * 2.0) for x, y, r in located]
    labels[1] = (labels[1][0] + 24.0, labels[1][1] - 15.0, labels[1][2] * 1.5)  # off by ~28 px, radius wrong
    reg = fit_registration(labels, located)
    assert (reg.dx_px, reg.dy_px, reg.radius_scale, reg.presses) == pytest.approx((3.0, -2.0, 0.5, 4))
    assert reg.place(10.0, 20.0, 30.0) == pytest.approx((13.0, 18.0, 15.0))
    assert reg.describe() == "labels registered on 4 presses: centre +3.0, -2.0 px, radius ×0.50"
    assert fit_registration([], []) == Registration() and Registration().place(1, 2, 3) == (1, 2, 3)


def test_a_correction_that_does_not_predict_the_press_left_out_is_not_taken():
    """Labels right on average, scattered: neither the centre offset nor the radius ratio is taken (the
    original GelSight's radii); one press cannot be checked, so nothing is taken from it."""
    located = [(100.0, 80.0, 20.0), (200.0, 60.0, 25.0), (150.0, 150.0, 22.0), (60.0, 190.0, 21.0)]
    scatter = [(2.0, -1.0, 1.06), (-2.0, 1.5, 0.95), (0.5, 2.0, 1.02), (-1.0, -2.0, 0.97)]
    labels = [(x + a, y + b, r * c) for (x, y, r), (a, b, c) in zip(located, scatter)]
    reg = fit_registration(labels, located)
    assert not reg.centre_taken and not reg.radius_taken and reg.place(5.0, 6.0, 7.0) == (5.0, 6.0, 7.0)
    assert reg.describe() == "labels taken as given (leaving presses out of 4: no gain)"
    one = fit_registration([(10.0, 10.0, 40.0)], [(13.0, 8.0, 20.0)])
    assert one.place(5.0, 6.0, 7.0) == (5.0, 6.0, 7.0) and one.presses == 1
    # a radius twice the contact on every press, centres scattered: the ratio alone is taken
    doubled = fit_registration([(x, y, 2 * r) for x, y, r in labels], located)
    assert doubled.radius_taken and not doubled.centre_taken
    assert doubled.describe() == "labels registered on 4 presses: centre as labelled, radius ×0.50"


@pytest.mark.parametrize(
    "labels, message",
    [
        ([(1.0, math.nan, 3.0)], "p0: label: expected finite centre and a radius > 0 px"),
        ([(1.0, 2.0, 0.0)], "p0: label: expected finite centre and a radius > 0 px"),
        ([(1.0, 2.0, math.inf)], "p0: label"),
        ([(1.0, 2.0, 100.0)], r"p0: located contact radius is ×0.10 the labelled one, expected ×0.25 to ×4"),
        ([(1.0, 2.0)], r"p0: label: expected \(centre x, centre y, radius\) px, got 2 values"),
        ([(1.0, 2.0, 3.0), (1.0, 2.0, 3.0)], "2 labelled presses but 1 located"),
        ([(1.0, "x", 3.0)], r"p0: label: expected numbers \(centre x, centre y, radius\) px, got \(1.0, 'x', 3.0\)"),
    ],
)
def test_labels_that_cannot_be_registered_are_one_line_naming_the_press(labels, message):
    with pytest.raises(RegistrationError, match=message):
        fit_registration(labels, [(1.0, 2.0, 10.0)], ["p0", "p1"][: len(labels)])


def test_labels_registered_on_three_found_presses_place_a_new_press_where_its_frame_shows_it():
    """Presses rendered at known places; their labels 3 px right, 2 px up and twice the contact's radius
    (the Mini's published radii are about that); found under the light, then a fourth press placed from
    its labels alone lands within half a pixel and 5 % of its radius."""
    bg = background()
    light = position_light(bg)
    truth = PressRender(provisional_profile(bg, MM_PER_PX, GEL, light), sphere(2 * BALL_MM))
    places = [(90.0, 70.0, 0.7), (230.0, 90.0, 0.8), (160.0, 170.0, 0.6), (120.0, 150.0, 0.75)]
    rng = np.random.default_rng(3)

    def radius_px(x: float, y: float, d: float) -> float:  # the solver's contact, as the calibration measures it
        area = truth.solve(truth.pose_of_pixel(x, y, -d), fields=frozenset()).normal.contact_area_mm2
        return math.sqrt(area / math.pi) / MM_PER_PX

    true_radius = [radius_px(*place) for place in places]
    labels = [(x + 3.0, y - 2.0, 2.0 * r) for (x, y, _), r in zip(places, true_radius)]
    found = []
    for x, y, d in places[:3]:
        c = locate_press(bg, Press(pressed(truth, bg, x, y, d, rng), BALL_MM), MM_PER_PX, light, gel=GEL)
        found.append((c.centre_x_px, c.centre_y_px, c.radius_px))
    reg = fit_registration(labels[:3], found)
    x, y, r = reg.place(*labels[3])
    assert abs(x - places[3][0]) < 0.5 and abs(y - places[3][1]) < 0.5, (x, y)
    assert abs(r / true_radius[3] - 1) < 0.05, (r, true_radius[3])


def test_a_press_labelled_wider_than_the_ball_can_reach_says_nothing_of_the_radius():
    """Three presses labelled beyond the solver's widest contact (64.5 px; their located contacts capped
    below it) and three labelled at twice their contact: the ratio comes from the three within reach."""
    located = [(100, 80, 20), (200, 60, 25), (150, 150, 64), (60, 190, 64.2), (9, 9, 64.1), (30, 40, 22)]
    labels = [(100, 80, 40), (200, 60, 50), (150, 150, 200), (60, 190, 214), (9, 9, 207), (30, 40, 44)]
    assert fit_registration(labels, located).radius_scale == pytest.approx(math.sqrt(0.5 * 64 / 200))  # six's median
    reg = fit_registration(labels, located, reach_px=64.5)
    assert reg.radius_taken and reg.radius_scale == pytest.approx(0.5)
    assert reg.describe().endswith("radius ×0.50 (of 3 within reach)")
    # a label far beyond reach (×0.1 of it) is left out, not refused
    far = labels[:2] + [(150, 150, 700)] + labels[3:]
    assert fit_registration(far, located, reach_px=64.5).radius_scale == pytest.approx(0.5)
    # two within reach check one press against one: not taken
    assert not fit_registration(labels[:5], located[:5], reach_px=64.5).radius_taken


def test_a_centre_offset_is_taken_only_from_presses_spread_over_the_field():
    located = [(100.0, 80.0, 20.0), (200.0, 60.0, 25.0), (150.0, 150.0, 22.0)]
    labels = [(x - 3.0, y + 2.0, r) for x, y, r in located]
    assert fit_registration(labels, located).centre_taken
    crowded = fit_registration(labels, located, spread=False)
    assert not crowded.centre_taken and crowded.place(1.0, 2.0, 3.0) == (1.0, 2.0, 3.0)
    assert not fit_registration(labels[:2], located[:2]).centre_taken  # two presses: one against one


def test_names_and_the_reach_are_checked_where_they_enter():
    located, labels = [(1.0, 2.0, 10.0)] * 2, [(1.0, 2.0, 12.0)] * 2
    with pytest.raises(RegistrationError, match="2 labelled presses but 1 names"):
        fit_registration(labels, located, ["p0"])
    for reach in (math.nan, -1.0, math.inf, 0.0):
        with pytest.raises(RegistrationError, match="reach_px: expected a finite number > 0 px"):
            fit_registration(labels, located, reach_px=reach)
    assert fit_registration(np.zeros((0, 3)), np.zeros((0, 3))) == Registration()  # arrays, not only lists
