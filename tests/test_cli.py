"""The `rig` command line, on the built-in simulated rig."""

import signal
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from cli.rig_app import app

runner = CliRunner()


def test_status_sim_prints_four_axes_and_the_wrench():
    result = runner.invoke(app, ["status", "--sim"])
    assert result.exit_code == 0, result.output
    for axis in ("x", "y", "z", "theta"):
        assert f"│ {axis} " in result.output
    for component in ("Fx", "Fy", "Fz", "Mx", "My", "Mz"):
        assert component in result.output


def test_jog_step_sim_moves_z_and_prints_the_new_position():
    result = runner.invoke(app, ["jog", "--axis", "z", "--step", "0.1", "--sim"])
    assert result.exit_code == 0, result.output
    assert result.stdout.strip() == "z = 5.1000 mm"  # the "moving" line goes to stderr


def test_jog_to_and_speed():
    result = runner.invoke(app, ["jog", "--axis", "x", "--to", "-1.5", "--speed", "2", "--sim"])
    assert result.exit_code == 0, result.output
    assert "x = -1.5000 mm" in result.output


def test_jog_interactive_keys(capsys):
    """The keys of interactive jogging, fed as a stream (a terminal's keys arrive the same way)."""
    import io

    from cli.interactive import jog_with_keys
    from rig.clock import ManualClock
    from rig.rig import Rig
    from rig.sim.rig_sim import SimulatedRig

    with SimulatedRig(ManualClock()) as sim, Rig.open(sim.config(), sim.clock, axes=("z",)) as rig:
        with rig.motion("jog") as m:
            jog_with_keys(m, "z", 0.2, None, stream=io.StringIO("++-]-q"))
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("z = ")]
    assert [line.split()[2] for line in lines] == ["5.0000", "5.2000", "5.4000", "5.2000", "3.2000"]


def test_interactive_jog_without_a_terminal_is_refused_in_one_line():
    result = runner.invoke(app, ["jog", "--axis", "x", "--sim"], input="")
    assert result.exit_code == 1
    assert result.output.strip() == (
        "error: interactive jogging needs a terminal (stdin is not one): run it in a terminal, or give --step or --to"
    )


def test_soft_limit_is_one_red_line_not_a_traceback():
    result = runner.invoke(app, ["jog", "--axis", "z", "--step", "-30", "--sim"])
    assert result.exit_code == 1
    assert "outside the soft limits" in result.output and "Traceback" not in result.output


def test_bad_config_names_file_and_key(tmp_path):
    cfg = tmp_path / "rig.toml"
    cfg.write_text('[axes.z]\ndriver = "servo"\n')
    result = runner.invoke(app, ["status", "--config", str(cfg)])
    assert result.exit_code == 1
    assert f"{cfg}: [axes.z.driver] must be one of 'zaber', 'pr_drive'" in result.output


def test_no_config_says_what_to_do(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("RIG_CONFIG", raising=False)
    result = runner.invoke(app, ["status"])
    assert result.exit_code == 1 and "--sim" in result.output


def test_home_and_zero_sim():
    result = runner.invoke(app, ["home", "--axis", "z", "--sim"])
    assert result.exit_code == 0, result.output
    assert "z homed, at 20.0000 mm" in result.output
    result = runner.invoke(app, ["zero", "--sim", "--samples", "10"])
    assert result.exit_code == 0, result.output
    assert "Fz +0.35" in result.output


def test_help_does_not_import_heavy_modules():
    code = (
        "import sys; from cli.rig_app import app; "
        "heavy = [m for m in ('torch', 'diffusers', 'cv2', 'pymodbus', 'serial', 'numpy', 'h5py') "
        "if m in sys.modules]; "
        "print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == ""


def test_sim_serve_then_status_from_another_process(tmp_path):
    cfg = tmp_path / "sim.toml"
    rig = str(Path(sys.executable).parent / "rig")
    server = subprocess.Popen(
        [rig, "sim", "serve", "--out", str(cfg), "--transport", "tcp"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        lines = []
        for line in server.stdout:
            lines.append(line)
            if line.startswith("serving"):
                break
        assert any(line.startswith("stages") for line in lines) and cfg.exists()
        result = subprocess.run(
            [rig, "jog", "--axis", "y", "--step", "0.25", "--config", str(cfg)],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert result.returncode == 0, result.stderr
        assert result.stdout.strip() == "y = 0.2500 mm"
        result = subprocess.run([rig, "status", "--config", str(cfg)], capture_output=True, text=True, timeout=60)
        assert "+0.2500" in result.stdout  # the state persisted in the serving process
    finally:
        server.send_signal(signal.SIGINT)
        try:
            out, _ = server.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            server.send_signal(signal.SIGUSR1)  # its threads' stacks, for the failure message
            try:
                _, err = server.communicate(timeout=5)
            except subprocess.TimeoutExpired:
                err = ""
            server.kill()
            server.communicate()
            pytest.fail(f"rig sim serve did not stop within 30 s of Ctrl-C; its threads:\n{err[-4000:]}")
    assert "stopped" in out


def test_train_reports_bad_input_in_one_line(tmp_path):
    bindir = Path(sys.executable).parent
    result = subprocess.run(
        [str(bindir / "train"), "--data", str(tmp_path / "nowhere"), "--out", str(tmp_path / "r")],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 1 and "no split.json" in result.stderr and "Traceback" not in result.stderr
