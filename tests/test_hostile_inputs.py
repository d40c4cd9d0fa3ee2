"""Hostile numbers and paths get one-line errors where they enter.

Each finding has a test that failed on the code before the checks (NaN limits loaded,
NaN shear ran as no shear, ``../`` frame files were read, a zero split part came out
empty...), then property tests: any number in any numeric key of a rig config, a
protocol or import metadata either loads or raises the project's one-line error naming
the file and the key — never another exception, never a hang.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import json
import math
import os
import signal
import string
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from acquisition.run_file import RunFileError
from cli.dataset_app import app as dataset_app
from cli.rig_app import app as rig_app
from common.errors import ConfigError
from dataset.interchange import import_run
from dataset.pose_convention import POSE_CONVENTION
from dataset.split import SplitError, make_split, parse_ratios
from protocols.plan import MAX_FRAMES, MAX_LEVELS, MAX_STEPS, Plan
from protocols.spec import load_protocol, parse_protocol
from rig.config import RigConfig, parse_config
from rig.sim.rig_sim import SimulatedRig

runner = CliRunner()


@contextlib.contextmanager
def time_limit(seconds: float):
    """Fail instead of hanging: SIGALRM interrupts a runaway loop in the main thread."""

    def expired(*_):
        raise TimeoutError(f"took longer than {seconds} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def one_line(message: str) -> str:
    assert "\n" not in message.strip() and "Traceback" not in message, message
    return message


# ---------------------------------------------------------------------------------------------
# Finding 2: a rig config with NaN/inf limits disarmed the force guard.


def sim_config_text(simulated: SimulatedRig) -> str:
    return simulated.config_toml(with_camera=False)


@pytest.mark.parametrize(
    "old, new, key",
    [
        ("max_force_N = [10.0, 10.0, 40.0]", "max_force_N = [nan, nan, nan]", "safety.max_force_N[0]"),
        ("max_force_N = [10.0, 10.0, 40.0]", "max_force_N = [10.0, 10.0, inf]", "safety.max_force_N[2]"),
        ("max_torque_Nmm = [300.0, 300.0, 200.0]", "max_torque_Nmm = [inf, 300.0, 200.0]", "safety.max_torque_Nmm[0]"),
        # the FT300 saturates at 327.67 N (int16 / 100): a higher limit can never trip
        ("max_force_N = [10.0, 10.0, 40.0]", "max_force_N = [10.0, 10.0, 400.0]", "safety.max_force_N[2]"),
        (
            "max_torque_Nmm = [300.0, 300.0, 200.0]",
            "max_torque_Nmm = [300.0, 300.0, 200.0]\npoll_s = nan",
            "safety.poll_s",
        ),
    ],
)
def test_nan_inf_and_unmeasurable_limits_refused_at_load(old, new, key):
    with SimulatedRig() as simulated:
        text = sim_config_text(simulated)
    assert old in text
    with pytest.raises(ConfigError) as err:
        parse_config(text.replace(old, new), "lab/rig.toml")
    assert one_line(str(err.value)).startswith(f"lab/rig.toml: [{key}] ")


@pytest.mark.parametrize(
    "pattern, value, key",
    [
        ("travel = [", "travel = [-inf, inf]\n#", "travel[0]"),
        ("max_speed = ", "max_speed = inf\n#", "max_speed"),
        ("max_speed = ", "max_speed = nan\n#", "max_speed"),
        ("timeout_s = ", "timeout_s = nan\n#", "timeout_s"),
        ("offset = ", "offset = -inf\n#", "offset"),
        ("scale = ", "scale = nan\n#", "scale"),
    ],
)
def test_nan_inf_axis_values_refused_at_load(pattern, value, key):
    with SimulatedRig() as simulated:
        text = sim_config_text(simulated)
    z = text.index("[axes.z]")
    at = text.index(pattern, z)
    with pytest.raises(ConfigError) as err:
        parse_config(text[:at] + value + text[at + len(pattern) :], "lab/rig.toml")
    assert one_line(str(err.value)).startswith(f"lab/rig.toml: [axes.z.{key}] ")


def test_jog_with_nan_force_limits_is_refused_before_anything_moves(tmp_path):
    """The issue's reproduction: `rig jog --axis z --to -4` against `rig sim serve` with
    max_force_N = [nan, nan, nan] exited 0 with the gauge saturated at 327 N."""
    with SimulatedRig() as simulated:
        cfg = tmp_path / "rig-sim.toml"
        cfg.write_text(
            sim_config_text(simulated).replace("max_force_N = [10.0, 10.0, 40.0]", "max_force_N = [nan, nan, nan]")
        )
        z = simulated.world.stages["z"]
        before = z.position(simulated.clock.now())
        result = runner.invoke(rig_app, ["jog", "--axis", "z", "--to", "-4", "--config", str(cfg)])
        assert z.position(simulated.clock.now()) == before
    assert result.exit_code == 1, result.output
    assert f"{cfg}: [safety.max_force_N[0]] must be a finite number, got nan" in one_line(result.output)


# ---------------------------------------------------------------------------------------------
# Finding 8: run-protocol --out.

QUICK_SETTINGS = ["--set", "motion.max_depth_mm=0.4", "--set", "motion.speed_mm_s=0.5"]


@pytest.fixture
def no_devices(monkeypatch):
    """Any attempt to open the simulated rig fails the test: --out is checked first."""
    import cli.simulated

    def opened(*_, **__):
        raise AssertionError("a device was opened before --out was checked")

    monkeypatch.setattr(cli.simulated, "simulated_rig_for", opened)


def test_out_onto_an_existing_run_is_refused_and_untouched(tmp_path, no_devices):
    existing = tmp_path / "run.h5"
    existing.write_bytes(b"precious captured data")
    stamp = existing.stat().st_mtime_ns
    result = runner.invoke(rig_app, ["run-protocol", "sphere10mm", "--sim", "--out", str(existing), *QUICK_SETTINGS])
    assert result.exit_code == 1 and isinstance(result.exception, SystemExit), result.output
    assert f"{existing}: [--out] exists" in one_line(result.output)
    assert existing.read_bytes() == b"precious captured data" and existing.stat().st_mtime_ns == stamp


def test_out_into_a_missing_directory_is_refused_before_any_device(tmp_path, no_devices):
    out = tmp_path / "nowhere" / "run.h5"
    result = runner.invoke(rig_app, ["run-protocol", "sphere10mm", "--sim", "--out", str(out), *QUICK_SETTINGS])
    assert result.exit_code == 1 and isinstance(result.exception, SystemExit), result.output
    assert f"[--out] directory {tmp_path / 'nowhere'} does not exist" in one_line(result.output)
    assert not out.parent.exists()


def test_out_into_a_read_only_directory_is_refused(no_devices):
    """Root writes anywhere, so as root the command runs with effective uid nobody (65534):
    the directory is then truly read-only for it (the kernel says so, not a mock)."""
    import acquisition.executor  # noqa: F401 - imported while still allowed to read every file
    import cli.protocol_cmds  # noqa: F401

    folder = Path(tempfile.mkdtemp(prefix="ro-run-"))  # in /tmp: every ancestor searchable by nobody
    # the protocol file beside it, readable by nobody wherever the checkout is (a 0700 clone, say)
    protocol = Path(tempfile.mkdtemp(prefix="ro-protocol-")) / "sphere10mm.toml"
    protocol.write_text(load_protocol("sphere10mm").text)
    protocol.parent.chmod(0o755)
    protocol.chmod(0o644)
    # the same command once while every file is readable: what it imports lazily is then loaded (a
    # checkout or .venv inside a 0700 folder is not readable by nobody)
    missing = protocol.parent / "missing" / "run.h5"
    runner.invoke(rig_app, ["run-protocol", str(protocol), "--sim", "--out", str(missing), *QUICK_SETTINGS])
    folder.chmod(0o555)  # root's: read-only to nobody, and to anyone without root
    as_root = os.geteuid() == 0
    if as_root:
        os.setegid(65534)
        os.seteuid(65534)
    try:
        result = runner.invoke(
            rig_app, ["run-protocol", str(protocol), "--sim", "--out", str(folder / "run.h5"), *QUICK_SETTINGS]
        )
    finally:
        if as_root:
            os.seteuid(0)
            os.setegid(0)
        folder.chmod(0o755)
    try:
        assert result.exit_code == 1 and isinstance(result.exception, SystemExit), result.output
        assert f"[--out] directory {folder} is not writable" in one_line(result.output)
        assert list(folder.iterdir()) == []
    finally:
        for child in folder.iterdir():
            child.unlink()
        folder.rmdir()
        protocol.unlink()
        protocol.parent.rmdir()


# ---------------------------------------------------------------------------------------------
# Finding 8: protocol values, --set, and the planner's caps.

BASE = load_protocol("sphere10mm").text


@pytest.mark.parametrize(
    "old, new, key",
    [
        ("max_depth_mm = 1.6", "max_depth_mm = inf", "motion.max_depth_mm"),
        ("approach_mm = 1.0", "approach_mm = nan", "motion.approach_mm"),
        ("depth_step_mm = 0.4", "depth_step_mm = 1e-300", "motion.depth_step_mm"),  # hung the planner
        ("shear_mm = 2.0", "shear_mm = nan", "motion.shear_mm"),  # ran as no shear
        ("twist_deg = 5.0", "twist_deg = nan", "motion.twist_deg"),  # ran as no twist
        (
            "shear_mm = 2.0",
            "shear_mm = 2.225073858507e-311",
            "motion.shear_mm",
        ),  # ZeroDivisionError (found by hypothesis)
        ("twist_deg = 5.0", "twist_deg = 5e-324", "motion.twist_deg"),
        ("rate_hz = 1.0", "rate_hz = -inf", "capture.rate_hz"),
    ],
)
def test_protocol_nan_inf_and_tiny_values_refused(old, new, key):
    assert old in BASE
    with time_limit(10), pytest.raises(ConfigError) as err:
        Plan.of(parse_protocol(BASE.replace(old, new), "my/p.toml"))
    assert one_line(str(err.value)).startswith(f"my/p.toml: [{key}] must be")


def test_planner_caps_levels_and_frames_naming_the_cap():
    many_levels = BASE.replace("depth_step_mm = 0.4", "depth_step_mm = 0.01")  # 160 levels
    with time_limit(10), pytest.raises(ConfigError, match=rf"\[motion.depth_step_mm\] .*cap is {MAX_LEVELS}"):
        Plan.of(parse_protocol(many_levels, "my/p.toml"))
    crawl = BASE.replace("speed_mm_s = 0.01", "speed_mm_s = 0.0001").replace("rate_hz = 1.0", "rate_hz = 100.0")
    with time_limit(10), pytest.raises(ConfigError, match=rf"\[capture.rate_hz\] .*cap is {MAX_FRAMES}"):
        Plan.of(parse_protocol(crawl, "my/p.toml"))


@pytest.mark.parametrize(
    "setting, key",
    [
        ("motion.speed_mm_s=nan", "motion.speed_mm_s"),
        ("motion.shear_mm=nan", "motion.shear_mm"),
        ("motion.max_depth_mm=1e999", "motion.max_depth_mm"),
        ("capture.rate_hz=0", "capture.rate_hz"),
    ],
)
def test_set_values_are_checked_like_the_file(setting, key):
    with pytest.raises(ConfigError) as err:
        load_protocol("sphere10mm", [setting])
    assert f"[{key}] must be" in one_line(str(err.value))


def test_set_cannot_smuggle_a_second_line(tmp_path):
    """A value with a newline used to be written as two lines: here it set shear_mm = 0
    (absent from this file) while the record showed only speed_mm_s as set."""
    path = tmp_path / "p.toml"
    path.write_text(BASE.replace("shear_mm = 2.0", ""))
    with pytest.raises(ConfigError, match=r"\[motion.speed_mm_s\] --set .*one TOML value on one line"):
        load_protocol(path, ["motion.speed_mm_s=0.1\nshear_mm = 0"])


# ---------------------------------------------------------------------------------------------
# Finding 8: dataset import.

COLUMNS = [
    "file",
    "t_frame_s",
    "Fx_N",
    "Fy_N",
    "Fz_N",
    "Mx_Nmm",
    "My_Nmm",
    "Mz_Nmm",
    "x_mm",
    "y_mm",
    "z_mm",
    "theta_deg",
    "phase",
    "level",
]


def import_folder(root: Path, rows: int = 2, meta: dict | None = None) -> Path:
    """A folder in the export format (docs/dataset.md): PNG frames, frames.csv, object.png, run.json."""
    folder = root / "folder"
    (folder / "frames").mkdir(parents=True)
    rng = np.random.default_rng(0)
    table = []
    for i in range(rows):
        cv2.imwrite(str(folder / f"frames/{i:06d}.png"), rng.integers(0, 255, (8, 8, 3), dtype=np.uint8))
        table.append(
            {
                "file": f"frames/{i:06d}.png",
                "t_frame_s": str(float(i)),
                "Fx_N": "0.1",
                "Fy_N": "-0.2",
                "Fz_N": "1.5",
                "Mx_Nmm": "3.0",
                "My_Nmm": "-2.0",
                "Mz_Nmm": "0.5",
                "x_mm": "0.0",
                "y_mm": "0.5",
                "z_mm": "-0.4",
                "theta_deg": "0.0",
                "phase": "press",
                "level": "1",
            }
        )
    cv2.imwrite(str(folder / "object.png"), np.full((8, 8, 3), 200, np.uint8))
    write_table(folder, table)
    (folder / "run.json").write_text(
        json.dumps(
            meta
            if meta is not None
            else {
                "mm_per_px": 0.0634,
                "object": "sphere10mm",
                "capture_hz": 1.0,
                "sensor": "rgb",
                "pose_convention": POSE_CONVENTION,
            }
        )
    )
    return folder


def write_table(folder: Path, table: list[dict]) -> None:
    with open(folder / "frames.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows(table)


def read_table(folder: Path) -> list[dict]:
    with open(folder / "frames.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def test_import_folder_is_valid_as_built(tmp_path):
    folder = import_folder(tmp_path)
    result = runner.invoke(dataset_app, ["import", str(folder), "--out", str(tmp_path / "ok.h5")])
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize(
    "meta, key, words",
    [
        ({"mm_per_px": "x"}, "mm_per_px", "must be a number, got 'x'"),
        ({"mm_per_px": -0.06}, "mm_per_px", "must be in [0.0001, 10.0], got -0.06"),
        ({"mm_per_px": float("nan")}, "mm_per_px", "must be a finite number, got nan"),
        ({"mm_per_px": 0.06, "capture_hz": 0}, "capture_hz", "must be in [0.01, 1000.0], got 0"),
        ({"mm_per_px": 0.06, "capture_hz": float("inf")}, "capture_hz", "must be a finite number, got inf"),
    ],
)
def test_import_metadata_refused_naming_run_json_and_key(tmp_path, meta, key, words):
    folder = import_folder(tmp_path, meta=meta)
    result = runner.invoke(dataset_app, ["import", str(folder), "--out", str(tmp_path / "x.h5")])
    assert result.exit_code == 1 and isinstance(result.exception, SystemExit), result.output
    assert f"{folder / 'run.json'}: [{key}] {words}" in one_line(result.output)
    assert not (tmp_path / "x.h5").exists()


@pytest.mark.parametrize(
    "column, value, words",
    [
        ("level", "300", "must be in [0, 127], got 300.0"),
        ("Fz_N", "nan", "must be a finite number, got nan"),
        ("Mz_Nmm", "-inf", "must be a finite number, got -inf"),
        ("x_mm", "1e300", "must be in [-10000.0, 10000.0], got 1e+300"),
        ("phase", "stroke", "unknown phase 'stroke'; expected one of approach, press"),
        ("file", "../../x.png", "'../../x.png' is outside"),
        ("file", "/etc/hostname", "'/etc/hostname' is outside"),
    ],
)
def test_import_rows_refused_naming_row_and_column(tmp_path, column, value, words):
    folder = import_folder(tmp_path)
    cv2.imwrite(str(tmp_path.parent / "x.png"), np.zeros((8, 8, 3), np.uint8))  # a readable file outside
    table = read_table(folder)
    table[1][column] = value
    write_table(folder, table)
    result = runner.invoke(dataset_app, ["import", str(folder), "--out", str(tmp_path / "x.h5")])
    assert result.exit_code == 1 and isinstance(result.exception, SystemExit), result.output
    assert f"frames.csv: [row 3, column {column}] " in one_line(result.output) and words in result.output
    assert not (tmp_path / "x.h5").exists()


def test_import_mm_per_px_option_is_finite_and_named(tmp_path):
    folder = import_folder(tmp_path)
    for value in ("nan", "inf", "-0.06"):
        result = runner.invoke(
            dataset_app, ["import", str(folder), "--out", str(tmp_path / "x.h5"), "--mm-per-px", value]
        )
        assert result.exit_code == 2 and "'--mm-per-px'" in result.output, result.output
    assert not (tmp_path / "x.h5").exists()


# ---------------------------------------------------------------------------------------------
# Finding 8: dataset split ratios.


@pytest.mark.parametrize(
    "ratio, words",
    [
        ("8:2:0", "[test] must be > 0, got 0.0"),
        ("0:1", "[train] must be > 0, got 0.0"),
        ("nan:1", "[train] must be a finite number, got nan"),
        ("1:inf", "[test] must be a finite number, got inf"),
        ("1:2:3:4", "two or three parts"),
    ],
)
def test_bad_ratios_name_the_ratio_and_the_part(ratio, words):
    with pytest.raises(SplitError) as err:
        parse_ratios(ratio)
    assert f"split ratio {ratio!r}" in one_line(str(err.value)) and words in str(err.value)


def test_huge_equal_ratios_are_an_even_split():
    assert parse_ratios("1e308:1e308") == (0.5, 0.5)


@pytest.fixture
def small_run(tmp_path):
    folder = import_folder(tmp_path / "src", rows=10)
    import_run(folder, tmp_path / "run.h5")
    return tmp_path / "run.h5"


def test_every_part_gets_a_frame_or_a_clear_error(small_run, tmp_path):
    split = make_split([small_run], "99:1", tmp_path / "s")
    assert {k: len(v) for k, v in split.parts.items()} == {"train": 9, "test": 1}
    split = make_split([small_run], "1e308:1e308", tmp_path / "t")
    assert {k: len(v) for k, v in split.parts.items()} == {"train": 5, "test": 5}
    result = runner.invoke(dataset_app, ["split", "8:2:0", str(small_run), "--out", str(tmp_path / "u")])
    assert result.exit_code == 1 and "[test] must be > 0" in one_line(result.output)
    result = runner.invoke(dataset_app, ["split", "nan:1", str(small_run), "--out", str(tmp_path / "v")])
    assert result.exit_code == 1 and "split ratio 'nan:1': [train]" in one_line(result.output)
    result = runner.invoke(dataset_app, ["split", "1:1", str(small_run), "--out", str(tmp_path / "w"), "--seed", "-1"])
    assert result.exit_code == 2 and "'--seed'" in result.output


def test_too_few_frames_for_the_parts_is_a_clear_error(tmp_path):
    folder = import_folder(tmp_path / "src", rows=2)
    import_run(folder, tmp_path / "two.h5")
    with pytest.raises(SplitError, match=r"2 frame\(s\) cannot fill 3 parts"):
        make_split([tmp_path / "two.h5"], "7:1:2", tmp_path / "s")


# ---------------------------------------------------------------------------------------------
# Finding 8: numeric options of rig commands (checked before any device is opened).


@pytest.mark.parametrize(
    "args, option",
    [
        (["jog", "--axis", "z", "--step", "nan"], "--step"),
        (["jog", "--axis", "z", "--to", "inf"], "--to"),
        (["jog", "--axis", "z", "--step", "1", "--speed", "inf"], "--speed"),
        (["jog", "--axis", "z", "--step", "1", "--speed", "0"], "--speed"),
        (["jog", "--axis", "z", "--key-step", "inf"], "--key-step"),
        (["find-contact", "--speed", "inf"], "--speed"),
        (["find-contact", "--max-travel", "nan"], "--max-travel"),
        (["find-contact", "--threshold-n", "inf"], "--threshold-n"),
        (["run-protocol", "sphere10mm", "--origin", "0,0,nan,0", "--dry-run"], "--origin"),
    ],
)
def test_numeric_rig_options_refuse_nan_inf_naming_the_option(tmp_path, args, option):
    missing = tmp_path / "no-such-rig.toml"  # were the option accepted, this would be the error instead
    result = runner.invoke(rig_app, [*args, "--config", str(missing)])
    # 2: typer refused the option; 1: the command refused it (--origin is parsed in the body)
    assert result.exit_code in (1, 2) and f"'{option}'" in result.output, result.output
    assert "no-such-rig.toml" not in result.output


# ---------------------------------------------------------------------------------------------
# Property tests: every number in every numeric key.

NASTY_FLOATS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 5e-324, 1e-300, 1e300, -1e300, math.nan, math.inf, -math.inf, 0.4, 1.6, 0.01]),
)
NASTY_INTS = st.one_of(st.integers(), st.sampled_from([0, -1, 1, 2**31, 2**63, 10**30]))
NASTY_SCALARS = st.one_of(
    NASTY_FLOATS, NASTY_INTS, st.booleans(), st.text(alphabet=string.ascii_letters + string.digits + " .-", max_size=6)
)
NASTY = st.one_of(NASTY_SCALARS, st.lists(st.one_of(NASTY_FLOATS, NASTY_INTS), max_size=4))


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)
    return "[" + ", ".join(toml_value(x) for x in v) + "]"


def toml_doc(tables: dict[str, dict]) -> str:
    return "\n".join(
        f"[{name}]\n" + "".join(f"{k} = {toml_value(v)}\n" for k, v in body.items()) for name, body in tables.items()
    )


RIG = {
    "axes.x": {
        "driver": "zaber",
        "port": "/dev/ttyUSB0",
        "baudrate": 115200,
        "device": 1,
        "axis_number": 1,
        "scale": 0.000047625,
        "offset": -12.5,
        "travel": [-12.5, 12.5],
        "max_speed": 5.0,
        "jog_speed": 1.0,
        "timeout_s": 0.5,
        "retries": 2,
    },
    "axes.theta": {
        "driver": "pr_drive",
        "unit": "deg",
        "port": "/dev/ttyUSB1",
        "baudrate": 38400,
        "device": 1,
        "pulses_per_rev": 10000,
        "travel_per_rev": 4.0,
        "offset": -180.0,
        "travel": [-90.0, 90.0],
        "max_speed": 30.0,
        "jog_speed": 5.0,
    },
    "gauge": {
        "driver": "ft300",
        "port": "/dev/ttyUSB2",
        "baudrate": 19200,
        "device_id": 9,
        "timeout_s": 0.5,
        "retries": 2,
        "fresh_after_s": 0.05,
    },
    "camera": {
        "driver": "v4l2",
        "device": "/dev/video0",
        "width": 320,
        "height": 240,
        "fps": 25.0,
        "exposure": 150.0,
        "white_balance_K": 4600.0,
        "discard_frames": 5,
        "mm_per_px": 0.0634,
    },
    "safety": {
        "max_force_N": [5.0, 5.0, 25.0],
        "max_torque_Nmm": [200.0, 200.0, 100.0],
        "poll_s": 0.02,
        "gel_thickness_mm": 3.0,
        "max_depth_fraction": 0.6,
        "stiffness_N_per_mm": 100.0,
        "overshoot_margin": 0.1,
    },
    "pendant": {"vendor_id": 0x256F, "product_id": 0xC635, "deadband": 0.15},
}
RIG_NUMERIC = [(t, k) for t, body in RIG.items() for k, v in body.items() if not isinstance(v, str)]


def all_numbers(obj):
    """Every number in a loaded config (dataclasses, dicts, tuples), for the finite check."""
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            yield from all_numbers(getattr(obj, f.name))
    elif isinstance(obj, dict):
        for v in obj.values():
            yield from all_numbers(v)
    elif isinstance(obj, (tuple, list)):
        for v in obj:
            yield from all_numbers(v)
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
        yield obj


PROPERTY = settings(
    max_examples=int(os.environ.get("HOSTILE_EXAMPLES", 150)),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)


@PROPERTY
@given(edits=st.lists(st.tuples(st.sampled_from(RIG_NUMERIC), NASTY), min_size=1, max_size=3))
def test_property_rig_config_loads_or_names_file_and_key(edits):
    tables = {t: dict(body) for t, body in RIG.items()}
    for (table, key), value in edits:
        tables[table][key] = value
    with time_limit(5):
        try:
            cfg = parse_config(toml_doc(tables), "prop/rig.toml")
        except ConfigError as err:
            message = one_line(str(err))
            assert message.startswith("prop/rig.toml: [") and err.path == "prop/rig.toml"
            assert any(err.key.startswith(table + ".") for (table, _), _ in edits), (err.key, edits)
            return
    assert isinstance(cfg, RigConfig)
    assert all(math.isfinite(v) for v in all_numbers(cfg) if isinstance(v, float))


PROTOCOL = {
    "protocol": {"name": "prop", "object": "sphere10mm", "sensor": "rgb"},
    "motion": {
        "depth_step_mm": 0.4,
        "max_depth_mm": 1.6,
        "shear_mm": 2.0,
        "twist_deg": 5.0,
        "speed_mm_s": 0.1,
        "twist_speed_deg_s": 0.25,
        "approach_mm": 1.0,
        "approach_speed_mm_s": 0.5,
    },
    "capture": {"rate_hz": 1.0},
}
PROTOCOL_NUMERIC = [(t, k) for t, body in PROTOCOL.items() for k, v in body.items() if not isinstance(v, str)]
PROTOCOL_KEYS = {f"{t}.{k}" for t, body in PROTOCOL.items() for k in body}


@PROPERTY
@given(edits=st.lists(st.tuples(st.sampled_from(PROTOCOL_NUMERIC), NASTY), min_size=1, max_size=3))
def test_property_protocol_plans_or_names_file_and_key(edits):
    tables = {t: dict(body) for t, body in PROTOCOL.items()}
    for (table, key), value in edits:
        tables[table][key] = value
    with time_limit(5):  # depth_step_mm = 1e-300 used to hang here
        try:
            plan = Plan.of(parse_protocol(toml_doc(tables), "prop/p.toml"))
        except ConfigError as err:
            assert one_line(str(err)).startswith("prop/p.toml: [") and err.key in PROTOCOL_KEYS, str(err)
            return
    assert len(plan.steps) <= MAX_STEPS and plan.frame_count <= MAX_FRAMES
    assert all(math.isfinite(v) for s in plan.steps for v in (*s.start, *s.end, s.duration_s))


CSV_NUMERIC = COLUMNS[1:12] + ["level"]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    meta=st.fixed_dictionaries({}, optional={"mm_per_px": NASTY, "capture_hz": NASTY}),
    cells=st.lists(
        st.tuples(
            st.integers(0, 1),
            st.sampled_from(CSV_NUMERIC + ["phase", "file"]),
            st.one_of(NASTY_SCALARS.map(str), st.sampled_from(["../x.png", "/x.png", "", "twist"])),
        ),
        max_size=2,
    ),
)
def test_property_import_metadata_loads_or_names_file_and_key(meta, cells):
    with tempfile.TemporaryDirectory() as tmp, time_limit(10):
        folder = import_folder(Path(tmp), meta=meta)
        table = read_table(folder)
        for row, column, value in cells:
            table[row][column] = value
        write_table(folder, table)
        try:
            frames = import_run(folder, Path(tmp) / "out.h5", mm_per_px=None if "mm_per_px" in meta else 0.06)
        except (ConfigError, RunFileError) as err:
            message = one_line(str(err))
            assert message.startswith(str(folder)), message
            assert (
                "run.json: [" in message
                or "frames.csv: [row" in message
                or "frames.csv: row" in message
                or "frame" in message
            ), message
            return
        assert frames == 2


def test_a_binary_file_given_as_the_rig_config_is_one_line(tmp_path):
    """`rig status --config notrun.h5` once printed `'utf-8' codec can't decode …`, naming nothing."""
    from typer.testing import CliRunner

    from cli.rig_app import app

    not_a_config = tmp_path / "notrun.h5"
    not_a_config.write_bytes(b"\x89HDF\r\n\x1a\n\x00\x00\xff\xfe")
    result = CliRunner().invoke(app, ["status", "--config", str(not_a_config)])
    assert result.exit_code == 1
    assert one_line(result.output).strip() == (
        f"error: {not_a_config}: [-] not a rig config: byte 0 is not UTF-8 text (a rig config is a TOML text file)"
    )
