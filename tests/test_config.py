"""Config validation: errors name the file, the key and what was allowed."""

import pytest

from common.errors import ConfigError
from rig.config import load_config, parse_config
from rig.sim.rig_sim import SimulatedRig

GOOD = """
[axes.z]
driver = "zaber"
port = "/dev/ttyUSB0"
device = 3
scale = -0.000047625
offset = 20.0
travel = [-5.0, 20.0]
max_speed = 2.0

[gauge]
driver = "ft300"
port = "/dev/ttyUSB1"

[safety]
max_force_N = [10.0, 10.0, 40.0]
max_torque_Nmm = [300.0, 300.0, 200.0]
gel_thickness_mm = 3.0
"""


def test_good_config_parses_with_defaults():
    cfg = parse_config(GOOD, "rig.toml")
    z = cfg.axes["z"]
    assert (z.driver, z.baudrate, z.unit, z.travel, z.jog_speed) == ("zaber", 115200, "mm", (-5.0, 20.0), 1.0)
    assert (cfg.gauge.baudrate, cfg.gauge.device_id, cfg.gauge.mode) == (19200, 9, "stream")


@pytest.mark.parametrize(
    "edit, key, words",
    [
        (("travel = [-5.0, 20.0]", "travel = [20.0, -5.0]"), "axes.z.travel", "low < high"),
        (("travel = [-5.0, 20.0]", 'travel = "wide"'), "axes.z.travel", "list of 2 numbers"),
        (('driver = "zaber"', 'driver = "stepper"'), "axes.z.driver", "'zaber', 'pr_drive'"),
        (("max_speed = 2.0", "max_speed = -1"), "axes.z.max_speed", "> 0"),
        (("max_speed = 2.0", "max_speed = 2.0\njog_speed = 3.0"), "axes.z.jog_speed", "must not exceed"),
        (("scale = -0.000047625", "scale = 0"), "axes.z.scale", "non-zero"),
        (("scale = -0.000047625\n", ""), "axes.z.scale", "is required"),
        (("device = 3", "device = 3\nspeed = 4"), "axes.z.speed", "unknown key"),
        (("[axes.z]", "[axes.w]"), "axes.w", "unknown axis"),
        (('port = "/dev/ttyUSB1"', 'port = "/dev/ttyUSB0"'), "gauge.port", "own port"),
        (("max_force_N = [10.0, 10.0, 40.0]", "max_force_N = [10.0, 40.0]"), "safety.max_force_N", "3 numbers"),
    ],
)
def test_bad_values_name_file_and_key(edit, key, words):
    text = GOOD.replace(*edit)
    with pytest.raises(ConfigError) as err:
        parse_config(text, "lab/rig.toml")
    message = str(err.value)
    assert message.startswith("lab/rig.toml: ") and f"[{key}]" in message and words in message


def test_axes_without_safety_or_gauge_refused():
    no_safety = GOOD[: GOOD.index("[safety]")]
    with pytest.raises(ConfigError, match=r"\[safety\] is required"):
        parse_config(no_safety, "r.toml")
    no_gauge = GOOD.replace('[gauge]\ndriver = "ft300"\nport = "/dev/ttyUSB1"\n', "")
    with pytest.raises(ConfigError, match=r"\[gauge\] is required"):
        parse_config(no_gauge, "r.toml")


def test_not_toml_and_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="not valid TOML"):
        parse_config("[axes\n", "broken.toml")
    with pytest.raises(ConfigError, match="file not found"):
        load_config(tmp_path / "nope.toml")


def test_shared_port_must_agree():
    text = (
        GOOD
        + """
[axes.x]
driver = "pr_drive"
port = "/dev/ttyUSB0"
pulses_per_rev = 10000
travel_per_rev = 5.0
travel = [-10.0, 10.0]
max_speed = 2.0
"""
    )
    with pytest.raises(ConfigError, match=r"axes.x.port.*shared with axis z"):
        parse_config(text, "r.toml")


def test_simulated_rig_writes_a_valid_config(tmp_path):
    with SimulatedRig(transport="tcp", gauge="m8128") as sim:
        path = tmp_path / "sim.toml"
        path.write_text(sim.config_toml())
        cfg = load_config(path)
    assert set(cfg.axes) == {"x", "y", "z", "theta"} and cfg.gauge.driver == "m8128"
    assert cfg.axes["x"].port.startswith("socket://127.0.0.1:")


def test_documented_example_config_is_valid():
    from pathlib import Path

    cfg = load_config(Path(__file__).parent.parent / "docs" / "rig.example.toml")
    assert set(cfg.axes) == {"x", "y", "z", "theta"}
    assert cfg.axes["z"].scale < 0 and cfg.pendant.vendor_id == 0x256F


@pytest.mark.parametrize(
    "value, words",
    [
        (float("nan"), "must be a finite number, got nan"),  # NaN passes every `low <= v <= high`
        (float("inf"), "must be a finite number, got inf"),
        (10**400, "must be a finite number"),  # an int too large for a float
        (True, "must be a number, got True"),  # bool is an int in Python
        ("1.0", "must be a number, got '1.0'"),
        (0.0, "must be > 0 and <= 300.0, got 0.0"),
        (300.5, "must be > 0 and <= 300.0, got 300.5"),
    ],
)
def test_finite_number_refuses_what_comparisons_let_through(value, words):
    from common.table import finite_number

    with pytest.raises(ConfigError) as err:
        finite_number("lab/rig.toml", "safety.max_force_N[2]", value, positive=True, high=300.0)
    assert str(err.value).startswith(f"lab/rig.toml: [safety.max_force_N[2]] {words}")
    assert finite_number("lab/rig.toml", "k", 40, positive=True, high=300.0) == 40.0
