"""Sensor profiles everywhere: the simulated rig, --sim commands, run files and evaluate's physics row."""

import dataclasses
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from acquisition import schema as S
from cli.rig_app import app
from model.conditioning.baseline import BaselineUnavailable, PhysicsRender
from rig.sim.rig_sim import SimulatedRig
from sensor_sim.light import LightModel
from sensor_sim.noise import SensorNoise
from sensor_sim.profile import (
    DEFAULT_PROFILE,
    ProfileError,
    default_profile,
    load_profile,
    profile_from_record,
)
from sensor_sim.profile_save import save_profile

runner = CliRunner()
QUICK = [  # sphere4mm to 0.4 mm, a small shear and twist: ~20 frames, a few seconds
    *("--set", "motion.max_depth_mm=0.4", "--set", "motion.depth_step_mm=0.4", "--set", "motion.shear_mm=0.1"),
    *("--set", "motion.twist_deg=0.5", "--set", "motion.speed_mm_s=0.05"),
]


def green_profile(path: Path, **changes) -> Path:
    """Another sensor: a green background, the shipped light reversed and halved, a 2 mm gel, no noise."""
    base = default_profile()
    light = LightModel(-0.5 * base.light.table_bgr, 0.2, "multiplicative", base.light.reference_bgr)
    w, h = changes.get("width_px", 300), changes.get("height_px", 300)
    background = np.zeros((h, w, 3), np.uint8)
    background[:] = (60, 170, 90)
    profile = dataclasses.replace(
        base,
        name="green",
        light=light,
        background=background,
        gel_thickness_mm=2.0,
        noise=SensorNoise((0.0, 0.0, 0.0)),
        format=2,
        **changes,
    )
    return save_profile(profile, path)


def test_simulated_rig_uses_the_profile_for_gel_and_camera(tmp_path):
    profile = load_profile(green_profile(tmp_path / "green.toml", width_px=128, height_px=128, mm_per_px=14 / 128))
    with SimulatedRig(profile=profile) as sim:
        assert sim.world.contact.solver.gel.thickness_mm == 2.0
        assert "width = 128" in sim.config_toml() and f"mm_per_px = {14 / 128!r}" in sim.config_toml()
        frame = sim.camera_source(height=128, width=128).render_now()  # the indenter starts above the gel
    assert frame.shape == (128, 128, 3)
    assert np.abs(frame.reshape(-1, 3).mean(axis=0) - (60, 170, 90)).max() < 1.0
    with SimulatedRig() as plain:  # no profile: the shipped one, as before
        assert plain.world.contact.solver.gel.thickness_mm == 3.0 and "width = 256" in plain.config_toml()


def test_a_non_square_profile_runs_on_the_simulated_rig_at_its_own_size(tmp_path):
    """A 320 × 240 sensor over 19.2 × 14.4 mm: the camera's frame, the config and the pad are its own."""
    profile = load_profile(green_profile(tmp_path / "wide.toml", width_px=320, height_px=240, mm_per_px=0.06))
    with SimulatedRig(profile=profile) as sim:
        config = sim.config_toml()
        assert "width = 320" in config and "height = 240" in config and f"mm_per_px = {0.06!r}" in config
        geometry = sim.world.contact.solver.geometry
        assert (geometry.width_mm, geometry.height_mm) == pytest.approx((19.2, 14.4))
        assert sim.camera_source().render_now().shape == (240, 320, 3)


def test_sim_commands_take_a_profile_and_refuse_a_bad_one(tmp_path):
    good = green_profile(tmp_path / "green.toml")
    ok = runner.invoke(app, ["status", "--sim", "--profile", str(good)])
    assert ok.exit_code == 0, ok.output
    without_sim = runner.invoke(app, ["status", "--profile", str(good)])
    assert without_sim.exit_code == 1 and "use it with --sim" in without_sim.output
    bad = tmp_path / "bad.toml"
    bad.write_text(good.read_text().replace("thickness_mm = 2.0", "thickness_mm = -1.0"))
    refused = runner.invoke(app, ["jog", "--axis", "z", "--step", "-0.1", "--sim", "--profile", str(bad)])
    assert refused.exit_code == 1 and "[gel] thickness_mm" in refused.output and str(bad) in refused.output
    assert "Traceback" not in refused.output and len(refused.output.strip().splitlines()) == 1


def test_a_run_records_its_profile_and_the_physics_row_finds_it(tmp_path):
    path = green_profile(tmp_path / "green.toml")
    profile = load_profile(path)
    run = tmp_path / "run.h5"
    result = runner.invoke(
        app, ["run-protocol", "sphere4mm", "--sim", "--profile", str(path), "--out", str(run), *QUICK]
    )
    assert result.exit_code == 0, result.output
    with h5py.File(run, "r") as f:
        record = f.attrs[S.ATTR_SENSOR_PROFILE]
        poses, frames = f[S.POSE_MEASURED][()], f[S.FRAMES][()]
    assert 'name = "green"' in record and profile.content_hash() in record and str(path.resolve()) in record
    k = int(np.argmin(poses[:, 2]))  # the deepest frame
    assert poses[k, 2] < -0.3
    by_default = PhysicsRender(str(run))
    assert by_default.profile.content_hash() == profile.content_hash()
    assert by_default.contact.solver.gel.thickness_mm == 2.0
    own = np.abs(by_default.render(poses[k]).astype(float) - frames[k]).mean()
    shipped = np.abs(PhysicsRender(str(run), profile=default_profile()).render(poses[k]).astype(float) - frames[k])
    assert own < 1.0 and shipped.mean() > 2 * own, (own, shipped.mean())
    path.write_text(path.read_text().replace("std_bgr = [0.0, 0.0, 0.0]", "std_bgr = [2.0, 2.0, 2.0]"))  # changed since
    with pytest.raises(BaselineUnavailable, match="green.*not there or has changed.*--profile"):
        PhysicsRender(str(run))
    assert PhysicsRender(str(run), profile=load_profile(path)).profile.noise.std_bgr == (2.0, 2.0, 2.0)


def test_a_plain_sim_run_records_the_shipped_profile():
    record = default_profile().record()
    assert profile_from_record(record) is default_profile()
    assert str(DEFAULT_PROFILE) in record


def test_the_content_hash_follows_content_not_the_file(tmp_path):
    base = default_profile()
    copy = load_profile(save_profile(base, tmp_path / "copy.toml"))
    assert copy.content_hash() == base.content_hash() and copy.path != base.path
    assert dataclasses.replace(base, gel_E_MPa=0.3).content_hash() != base.content_hash()
    background = base.background.copy()
    background[0, 0, 0] ^= 1
    assert dataclasses.replace(base, background=background).content_hash() != base.content_hash()
    with pytest.raises(ProfileError, match="lacks sha256"):
        profile_from_record('name = "x"\nfile = ""\n')
