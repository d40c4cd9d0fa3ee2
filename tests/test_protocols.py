"""Protocols are pure: tested by their steps, durations and frame counts."""

import math

import pytest

from common.errors import ConfigError
from protocols.plan import Plan, expand
from protocols.spec import load_protocol, parse_protocol, protocol_names


def test_library_has_the_papers_objects():
    names = set(protocol_names())
    assert {"sphere10mm", "sphere15mm", "sphere4mm", "circle8mm", "circle4mm", "square", "ring", "heart"} <= names
    assert {"woven", "irregular"} & names  # a texture board
    for name in names:
        load_protocol(name)  # every shipped file is valid


def test_sphere10mm_steps_follow_the_paper():
    steps = expand(load_protocol("sphere10mm"))
    level1 = [(s.phase, s.end) for s in steps if s.level == 1]
    assert level1 == [
        ("press", (0.0, 0.0, -0.4, 0.0)),
        ("shear", (0.0, 2.0, -0.4, 0.0)),
        ("shear", (2.0, 2.0, -0.4, 0.0)),
        ("return", (0.0, 0.0, -0.4, 0.0)),
        ("shear", (0.0, -2.0, -0.4, 0.0)),
        ("shear", (-2.0, -2.0, -0.4, 0.0)),
        ("return", (0.0, 0.0, -0.4, 0.0)),
        ("twist", (0.0, 0.0, -0.4, 5.0)),
        ("untwist", (0.0, 0.0, -0.4, 0.0)),
    ]
    assert [s.end[2] for s in steps if s.phase == "press"] == pytest.approx([-0.4, -0.8, -1.2, -1.6])
    assert steps[0].phase == "approach" and not steps[0].captured
    assert steps[-1].phase == "retract" and steps[-1].end[2] == 1.0


def test_durations_and_frame_count():
    plan = Plan.of(load_protocol("sphere10mm"))
    diag = next(s for s in plan.steps if s.phase == "return")
    assert diag.duration_s == pytest.approx(2 * math.sqrt(2) / 0.01)  # a straight line at 0.01 mm/s
    assert diag.speeds == pytest.approx({"x": 0.01 / math.sqrt(2), "y": 0.01 / math.sqrt(2)})
    per_level = 0.4 / 0.01 + 4 * 2 / 0.01 + 2 * 2 * math.sqrt(2) / 0.01 + 2 * 5 / 0.25
    assert plan.captured_duration_s == pytest.approx(4 * per_level)
    assert plan.frame_count == math.floor(4 * per_level) + 1 == 5783  # ~1.6 h at 1 Hz, as docs/reference.md works out


def test_pose_timeline_is_continuous():
    plan = Plan.of(load_protocol("sphere10mm"))
    assert plan.pose_at(0.0) == (0.0, 0.0, 0.0, 0.0)
    assert plan.pose_at(20.0) == pytest.approx((0.0, 0.0, -0.2, 0.0))
    assert plan.pose_at(40.0 + 100.0) == pytest.approx((0.0, 1.0, -0.4, 0.0))
    assert plan.pose_at(plan.captured_duration_s)[2] == pytest.approx(-1.6)


BASE = load_protocol("sphere10mm").text


@pytest.mark.parametrize(
    "edit, key, words",
    [
        (('object = "sphere10mm"', 'object = "teapot"'), "protocol.object", "sphere10mm"),
        (("speed_mm_s = 0.01", "speed_mm_s = -1"), "motion.speed_mm_s", "[0.0001, 10.0]"),
        (("max_depth_mm = 1.6", "max_depth_mm = 1.5"), "motion.max_depth_mm", "whole number of depth steps"),
        (("twist_deg = 5.0", "twist_deg = 5.0\nwobble = 1"), "motion.wobble", "unknown key"),
        (('sensor = "rgb"', 'sensor = "sonar"'), "protocol.sensor", "rgb_markers"),
    ],
)
def test_malformed_protocol_names_file_and_key(edit, key, words):
    with pytest.raises(ConfigError) as err:
        parse_protocol(BASE.replace(*edit), "my/protocol.toml")
    assert str(err.value).startswith("my/protocol.toml: ") and f"[{key}]" in str(err.value) and words in str(err.value)


def test_unknown_protocol_lists_the_library(tmp_path):
    with pytest.raises(ConfigError, match="sphere10mm"):
        load_protocol("nonesuch")
    with pytest.raises(ConfigError, match="not valid TOML"):
        parse_protocol("[protocol\n", "bad.toml")


def test_set_changes_keys_and_the_stored_text_records_them():
    p = load_protocol("sphere10mm", ["motion.speed_mm_s=0.1", "protocol.sensor=rgb_markers", "capture.rate_hz=2"])
    assert (p.speed_mm_s, p.sensor, p.capture_hz) == (0.1, "rgb_markers", 2.0)
    again = parse_protocol(p.text, p.path)
    assert (again.speed_mm_s, again.sensor, again.capture_hz) == (0.1, "rgb_markers", 2.0)
    # at 0.1 mm/s the paper's sequence is ~700 frames per object (docs/reference.md, "The acquisition protocol")
    assert 650 <= Plan.of(load_protocol("sphere10mm", ["motion.speed_mm_s=0.1"])).frame_count <= 800
    base = load_protocol("sphere10mm")
    assert Plan.of(base).frame_count > 5000


@pytest.mark.parametrize(
    "setting,words",
    [
        ("motion.sped=1", "motion.sped"),  # unknown key, named
        ("speed=1", "section.key=value"),  # no section
        ("motion.speed_mm_s=fast", "motion.speed_mm_s"),  # a string where a number belongs
        ("motion.speed_mm_s=50", "motion.speed_mm_s"),  # out of range
    ],
)
def test_bad_set_values_name_the_key(setting, words):
    with pytest.raises(ConfigError, match=words.replace(".", r"\.")):
        load_protocol("sphere10mm", [setting])
