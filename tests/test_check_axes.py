"""`rig check-axes` (rig/axis_check.py, axis_verdict.py, axis_fix.py, contact_image.py) on the simulated
rig on discrete-event time: the correct config passes, a y mirrored in the config and a swapped x/y are
found and fixed; the fix is written atomically with a backup and keeps the config's comments."""

from __future__ import annotations

import contextlib
import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rig.axis_check import CheckSettings, check_axes
from rig.axis_fix import fixed_config_text, write_config
from rig.axis_verdict import AxisFix, judge, nearest_signed_permutation
from rig.clock import ManualClock
from rig.config import load_config, parse_config
from rig.contact_image import GelContactImages
from rig.contact_search import find_contact
from rig.rig import Rig
from rig.sim.rig_sim import SimulatedRig

runner = CliRunner()
TRUE_SURFACE = 0.0  # the simulated gel's surface in axis z


def section(text: str, name: str) -> tuple[int, int]:
    start = text.index(f"[axes.{name}]")
    following = re.search(r"^\[", text[start + 1 :], re.M)
    return start, start + 1 + following.start() if following else len(text)


def mirror(text: str, name: str) -> str:
    """A stage's direction written the wrong way round: scale and offset negated (travel is symmetric)."""
    start, end = section(text, name)
    body = re.sub(r"^scale = (\S+)$", lambda m: f"scale = {-float(m.group(1))!r}", text[start:end], flags=re.M)
    body = re.sub(r"^offset = (\S+)$", lambda m: f"offset = {-float(m.group(1))!r}", body, flags=re.M)
    return text[:start] + body + text[end:]


def swap_xy(text: str) -> str:
    """x and y wired the other way round on the Zaber chain: their device numbers exchanged."""
    (xs, xe), (ys, ye) = section(text, "x"), section(text, "y")
    x = re.sub(r"^device = 1$", "device = 2", text[xs:xe], flags=re.M)
    y = re.sub(r"^device = 2$", "device = 1", text[ys:ye], flags=re.M)
    assert x != text[xs:xe] and y != text[ys:ye]
    return text[:xs] + x + text[xe:ys] + y + text[ye:]


@contextlib.contextmanager
def simulated(edit=lambda text: text, path: Path | None = None):
    """(simulated rig, rig on its config as edited, the config as written by the simulator) on
    discrete-event time; the edited config written to ``path`` when given (and loaded from there, as
    `--config` does)."""
    with SimulatedRig(ManualClock()) as sim:
        sim.triggered_camera = True
        original = sim.config_toml()
        text = edit(original)
        if path is not None:
            path.write_text(text)
            cfg = load_config(path)
        else:
            cfg = parse_config(text, "<edited simulated rig>")
        with Rig.open(cfg, sim.clock, camera=True, sim=sim) as rig:
            yield sim, rig, original


def judged(rig):
    rig.tare(10)
    find_contact(rig)
    return judge(check_axes(rig), rig.config.camera.mm_per_px)


def check(edit=lambda text: text):
    """(verdict, the config as edited, as the simulator wrote it)."""
    with simulated(edit) as (_sim, rig, original):
        return judged(rig), edit(original), original


@pytest.mark.slow
def test_the_simulated_rig_as_configured_passes():
    verdict, _, _ = check()
    assert verdict.ok, verdict.findings
    assert not verdict.fix.needed
    m = verdict.image_px_per_mm
    assert m[0, 0] > 15 and m[1, 1] > 15 and abs(m[0, 1]) < 1 and abs(m[1, 0]) < 1, m  # +x right, +y up
    assert verdict.mm_per_px_seen == pytest.approx(0.0546875, rel=0.03)  # the profile's 14 mm over 256 px
    assert verdict.gauge == "agrees with the camera"
    assert verdict.theta.startswith("+theta turns counter-clockwise")
    assert abs(verdict.centre_offset_px[0]) < 1.5 and abs(verdict.centre_offset_px[1]) < 1.5  # pose 0: centred
    assert abs(verdict.rotation_deg) < 1


@pytest.mark.slow
def test_the_centring_aid_gives_the_move_back_to_the_centre():
    """Started 1.2 mm right of and 0.4 mm below the contact point, the check's centring move is the
    way back (the simulated contact point is the middle of the frame)."""
    with simulated() as (_sim, rig, _original):
        with rig.motion("off centre") as m:
            m.move({"x": 1.2, "y": -0.4})
        verdict = judged(rig)
    assert verdict.ok, verdict.findings
    # the contact's centre is found within ~1.5 px (0.08 mm) of the truth: a centring aid, not a measurement
    assert verdict.centring_mm["x"] == pytest.approx(-1.2, abs=0.1)
    assert verdict.centring_mm["y"] == pytest.approx(0.4, abs=0.1)
    right, up = verdict.centre_offset_px
    assert right == pytest.approx(1.2 / 0.0546875, abs=2) and up == pytest.approx(-0.4 / 0.0546875, abs=2)


@pytest.mark.slow
def test_a_y_mirrored_in_the_config_is_found_and_fixed():
    verdict, text, original = check(lambda t: mirror(t, "y"))
    assert not verdict.ok
    assert any(line.startswith("stage +y moves the contact down in the image") for line in verdict.findings)
    assert not any("stage +x" in line for line in verdict.findings), verdict.findings
    assert verdict.fix == AxisFix(xy=(("x", 1), ("y", -1)))
    assert verdict.gauge == "agrees with the camera"  # the gauge sees the same physical motion
    fixed = parse_config(fixed_config_text(text, "<edited>", verdict.fix), "<edited>")
    assert fixed.axes == parse_config(original, "<edited>").axes  # the simulator's own config again


@pytest.mark.slow
def test_swapped_x_and_y_are_found_and_fixed():
    verdict, text, original = check(swap_xy)
    assert not verdict.ok
    assert any(line.startswith("stage +x moves the contact up in the image") for line in verdict.findings)
    assert any(line.startswith("stage +y moves the contact right in the image") for line in verdict.findings)
    assert verdict.fix == AxisFix(xy=(("y", 1), ("x", 1))) and verdict.fix.swapped
    fixed = parse_config(fixed_config_text(text, "<edited>", verdict.fix), "<edited>")
    assert fixed.axes["x"].device == 1 and fixed.axes["y"].device == 2  # the stages back under their names
    assert fixed.axes == parse_config(original, "<edited>").axes


@pytest.mark.slow
def test_the_fixed_config_passes_the_check(tmp_path):
    """Mirrored y and swapped x/y at once: found, fixed in the file, and the fixed file passes."""
    path = tmp_path / "rig.toml"
    with simulated(lambda t: swap_xy(mirror(t, "y")), path) as (sim, rig, _original):
        verdict = judged(rig)
        rig.close()
        assert verdict.fix == AxisFix(xy=(("y", -1), ("x", 1)))
        backup = write_config(path, fixed_config_text(path.read_text(), str(path), verdict.fix))
        assert backup.read_text() != path.read_text() and backup.name.startswith("rig.toml.bak-")
        with Rig.open(load_config(path), sim.clock, camera=True, sim=sim) as fixed_rig:
            again = judged(fixed_rig)
    assert again.ok, again.findings


@pytest.mark.slow
def test_rig_check_axes_sim_passes_and_prints_the_centring_move():
    from cli.rig_app import app

    result = runner.invoke(app, ["check-axes", "--sim"])
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "ok: stage +x moves the contact right in the image" in out
    assert "ok: stage +y moves the contact up in the image" in out
    assert re.search(r"scale seen 0\.05\d+ mm/px .*the config says 0\.0546875", out), out
    assert "contact pressed at column 1" in out
    # the simulated rig starts over the middle of the gel: centred within the aid's 0.1 mm, no jog proposed
    assert "centred over the gel within 0.1 mm at x = 0.000 mm, y = 0.000 mm" in out, out
    assert out.rstrip().endswith("axes agree with the camera")
    assert "Traceback" not in result.output


@pytest.mark.slow
def test_rig_check_axes_fix_writes_the_config_and_the_next_check_passes(tmp_path, monkeypatch):
    """The command end to end on a config file (a mirrored y), the rig opened on discrete-event
    time: exit 2 and the fix shown; --fix writes it (a backup beside it); the next run passes."""
    import cli.session
    from cli.rig_app import app

    path = tmp_path / "rig.toml"
    with SimulatedRig(ManualClock()) as sim:
        sim.triggered_camera = True
        path.write_text("# my rig\n" + mirror(sim.config_toml(), "y"))

        @contextlib.contextmanager
        def open_on_the_simulator(config, sim_flag, **options):
            assert config == path and not sim_flag
            with Rig.open(load_config(config), sim.clock, camera=True, sim=sim) as rig:
                yield rig

        monkeypatch.setattr(cli.session, "open_rig", open_on_the_simulator)
        found = runner.invoke(app, ["check-axes", "--config", str(path)])
        assert found.exit_code == 2, found.output
        assert "problem: stage +y moves the contact down in the image" in found.stdout
        assert f"fix: rig check-axes --fix writes this into {path}" in found.stdout
        assert "  y reversed" in found.stdout
        assert "# my rig" in path.read_text() and not list(tmp_path.glob("rig.toml.bak-*"))  # never silently
        fixed = runner.invoke(app, ["check-axes", "--config", str(path), "--fix"])
        assert fixed.exit_code == 2, fixed.output  # this run found the problem; the file is fixed now
        (backup,) = tmp_path.glob("rig.toml.bak-*")
        assert f"fixed: wrote {path} (the old file kept as {backup})" in fixed.stdout
        assert backup.read_text().startswith("# my rig") and "# my rig" in path.read_text()
        again = runner.invoke(app, ["check-axes", "--config", str(path)])
        assert again.exit_code == 0, again.output
        assert again.stdout.rstrip().endswith("axes agree with the camera")


@pytest.mark.slow
@pytest.mark.realtime  # the rig serves on this process's threads: under load its gauge samples age past the guard
@pytest.mark.timeout(360)  # its waits: 120 + 60 + 60 s of real time
@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
def test_a_signal_while_the_check_drags_the_contact_stops_and_lifts(tmp_path, signame):
    """The check's moves are a motion session's: a signal while the pressed indenter is dragged back
    stops every axis, lifts z clear of the gel and leaves the rig usable (served devices, real time)."""
    import signal
    import subprocess

    from test_motion_guard import RIG_BIN, lines_of, wait_for_line

    with SimulatedRig(transport="pty") as sim:
        sim.serve_camera()
        cfg = tmp_path / "rig-sim.toml"
        cfg.write_text(sim.config_toml())
        with Rig.open(load_config(cfg), sim.clock, sim=sim) as rig:  # as after `rig find-contact` (its own tests)
            rig.tare(20)  # z starts clear of the gel
            rig.state.remember_surface(TRUE_SURFACE, "find-contact")
        proc = subprocess.Popen(
            [RIG_BIN, "check-axes", "--config", str(cfg)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        try:
            lines = lines_of(proc.stderr)
            wait_for_line(lines, "x: moving to 1.0000 mm", 120)  # pressed, lifted, moved in the air
            wait_for_line(lines, "x: moving to 0.0000 mm", 60)  # pressed, dragged back: in contact
            assert sim.world.stages["x"].busy(sim.clock.now()), "the check said it drags, but x is idle"
            proc.send_signal(getattr(signal, signame))
            rc = proc.wait(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        err = proc.stderr.read() if proc.stderr else ""
        assert rc == 128 + getattr(signal, signame), (rc, err)
        assert "Traceback" not in err
        assert not any(s.busy(sim.clock.now()) for s in sim.world.stages.values())
        status = subprocess.run([RIG_BIN, "status", "--config", str(cfg)], capture_output=True, text=True, timeout=60)
        assert status.returncode == 0, status.stderr
        (z_row,) = [line for line in status.stdout.splitlines() if line.strip("│ ").startswith("z ")]
        assert float(z_row.split("│")[2]) > TRUE_SURFACE, z_row  # lifted clear of the gel


def test_a_press_deeper_than_the_depth_guard_is_refused_before_anything_moves():
    from cli.rig_app import app

    result = runner.invoke(app, ["check-axes", "--sim", "--depth-mm", "3"])
    assert result.exit_code == 1
    assert result.output.strip() == (
        "error: check-axes: a press 3 mm deep is deeper than the depth guard allows (1.80 mm, 60% of the 3 mm gel); "
        "nothing moved"
    )


def test_fix_refused_on_the_built_in_simulated_rig():
    from cli.rig_app import app

    result = runner.invoke(app, ["check-axes", "--sim", "--fix"])
    assert result.exit_code == 1
    assert "rig sim serve" in result.output and "Traceback" not in result.output


# -- the pieces -----------------------------------------------------------------------------------------


EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "rig.example.toml"


def test_the_fix_keeps_comments_and_changes_only_what_it_says():
    text = EXAMPLE.read_text()
    new = fixed_config_text(text, "rig.toml", AxisFix(xy=(("y", -1), ("x", 1)), theta_sign=-1))
    old_cfg, new_cfg = parse_config(text, "rig.toml"), parse_config(new, "rig.toml")
    assert new_cfg.axes["x"].device == old_cfg.axes["y"].device  # y's stage is x now, reversed
    assert new_cfg.axes["x"].options["scale"] == -old_cfg.axes["y"].options["scale"]
    assert new_cfg.axes["x"].offset == -old_cfg.axes["y"].offset
    assert new_cfg.axes["x"].travel == (-old_cfg.axes["y"].travel[1], -old_cfg.axes["y"].travel[0])
    assert (
        new_cfg.axes["y"].device == old_cfg.axes["x"].device and new_cfg.axes["y"].options == old_cfg.axes["x"].options
    )
    assert new_cfg.axes["theta"].options["travel_per_rev"] == -old_cfg.axes["theta"].options["travel_per_rev"]
    assert new_cfg.axes["z"] == old_cfg.axes["z"] and new_cfg.safety == old_cfg.safety
    kept = [line for line in text.splitlines() if line.lstrip().startswith("#")]
    assert kept == [line for line in new.splitlines() if line.lstrip().startswith("#")]  # every comment kept
    assert "# mm per microstep (0.047625 um); negative flips the direction" in new


def test_axes_the_fix_cannot_rewrite_are_refused_in_one_line():
    from common.errors import ConfigError

    text = EXAMPLE.read_text()
    start, end = section(text, "y")
    inline = (
        text[:start]
        + text[end:]
        + '\n[axes]\ny = { driver = "zaber", port = "/dev/ttyUSB0", device = 2, '
        + ("scale = 0.000047625, offset = -12.5, travel = [-12.5, 12.5], max_speed = 5.0 }\n")
    )
    with pytest.raises(ConfigError) as err:
        fixed_config_text(inline, "rig.toml", AxisFix(xy=(("x", 1), ("y", -1))))
    assert "rig.toml" in str(err.value) and "by hand" in str(err.value) and "\n" not in str(err.value)


def test_write_config_is_atomic_and_keeps_a_backup(tmp_path):
    path = tmp_path / "rig.toml"
    path.write_text("old\n")
    first = write_config(path, "new\n", now=0.0)
    second = write_config(path, "newer\n", now=0.0)  # the same second: a backup is never overwritten
    assert path.read_text() == "newer\n" and first.read_text() == "old\n" and second.read_text() == "new\n"
    assert first != second and not list(tmp_path.glob(".*.tmp"))


def test_nearest_signed_permutation():
    assert np.array_equal(nearest_signed_permutation(np.array([[18.0, 0.5], [-0.3, 18.0]])), np.eye(2))
    assert np.array_equal(nearest_signed_permutation(np.array([[0.1, 18.0], [-18.0, 0.2]])), [[0, 1], [-1, 0]])


def blob(size: int, centre: tuple[float, float], radius: float, markers: bool) -> np.ndarray:
    """A synthetic frame: a lit gel (a brightness gradient), a dimmed disc of contact, dark markers."""
    rows, cols = np.mgrid[0:size, 0:size].astype(np.float64)
    base = 120 + 60 * cols / size + 20 * rows / size
    disc = np.exp(-((cols - centre[0]) ** 2 + (rows - centre[1]) ** 2) / (2 * radius**2))
    image = np.stack([base * (1 - 0.5 * disc), base * (1 + 0.3 * disc), base], axis=2)
    if markers:
        on_grid = ((cols % 13) - 6) ** 2 + ((rows % 13) - 6) ** 2 < 6
        image[on_grid] *= 0.3
    return np.clip(image, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("markers", [False, True])
def test_contact_centre_and_shift_on_a_lit_gel(markers):
    images = GelContactImages()
    reference = blob(256, (0, 0), 1e-3, markers)  # nothing pressed
    a, b = blob(256, (150.0, 110.0), 20, markers), blob(256, (170.0, 101.0), 20, markers)
    assert images.centre(reference, reference) is None  # no contact: nothing changed
    for frame, (x, y) in ((a, (150.0, 110.0)), (b, (170.0, 101.0))):
        cx, cy = images.centre(reference, frame)
        assert abs(cx - x) < 1.0 and abs(cy - y) < 1.0, (cx, cy, x, y)
    dx, dy = images.shift(reference, a, b)
    assert abs(dx - 20) < 1.0 and abs(dy + 9) < 1.0, (dx, dy)


def test_check_settings_are_checked():
    from rig.errors import RigError

    for bad in (CheckSettings(step_mm=float("nan")), CheckSettings(twist_deg=0.0), CheckSettings(depth_mm=-1.0)):
        with pytest.raises(RigError, match="check-axes"):
            bad.check()
