"""The command line a researcher meets in the first hour on a rig (issue 28): a complete origin from
find-contact (stored with --set-origin, used and named by run-protocol), whole lines in logs, units on
the progress line, `rig status` without "-0.0000", `rig sim serve` cleaning up after itself, and a
protocol-name typo answered with "did you mean"."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from cli.rig_app import app

runner = CliRunner()
RIG = str(Path(sys.executable).parent / "rig")
EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "rig.example.toml"


@pytest.mark.realtime  # the built-in rig serves on threads: starved, its gauge samples age past the guard
def test_find_contact_prints_a_complete_origin():
    result = runner.invoke(app, ["find-contact", "--sim"])
    assert result.exit_code == 0, result.output
    match = re.search(r"^origin: x,y,z,theta = (\S+)$", result.stdout, re.M)
    assert match, result.stdout
    x, y, z, theta = (float(v) for v in match.group(1).split(","))
    assert (x, y, theta) == (0.0, 0.0, 0.0) and -0.3 < z < 0.0  # the simulated rig starts over the contact point
    assert f"use: rig run-protocol NAME --origin {match.group(1)}" in result.stdout
    assert "X,Y" not in result.stdout and "THETA" not in result.stdout


def test_find_contact_set_origin_on_the_built_in_rig_says_it_is_not_kept():
    result = runner.invoke(app, ["find-contact", "--sim", "--set-origin"])
    assert result.exit_code == 0, result.output
    assert "origin stored for this process only" in result.stdout


def test_a_stored_origin_is_checked_kept_and_used_by_run_protocol(tmp_path, rig_state_dir):
    """The origin in the rig's remembered state: written atomically, read back checked, named by
    run-protocol when it starts from it; a damaged one is one line naming the file and key."""
    import json

    from cli.protocol_cmds import resolve_origin
    from common.errors import ConfigError
    from rig.config import load_config
    from rig.rig_state import RigState

    cfg_path = tmp_path / "rig.toml"
    cfg_path.write_text(EXAMPLE.read_text())
    state = RigState.for_config(load_config(cfg_path))
    assert resolve_origin(None, cfg_path, sim=False)[1].startswith("the default: no --origin given")
    state.remember_origin((1.5, -2.0, -0.125, 3.0))
    assert RigState.for_config(load_config(cfg_path)).origin.values == (1.5, -2.0, -0.125, 3.0)
    origin, said = resolve_origin(None, cfg_path, sim=False)
    assert origin == (1.5, -2.0, -0.125, 3.0) and "remembered by rig find-contact --set-origin" in said
    assert resolve_origin((0.0, 0.0, 0.0, 0.0), cfg_path, sim=False)[1] == "from --origin"
    result = runner.invoke(app, ["run-protocol", "sphere10mm", "--config", str(cfg_path), "--dry-run"])
    assert (
        "origin: x,y,z,theta = 1.5000,-2.0000,-0.1250,3.0000 (remembered by rig find-contact --set-origin"
        in result.output
    )
    data = json.loads(state.path.read_text())
    data["origin"]["xyzt"] = [1.0, float("nan"), 0.0, 0.0]
    state.path.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=r"\[origin.xyzt\] must be 4 finite number"):
        RigState.for_config(load_config(cfg_path))


def test_run_protocol_says_which_origin_it_used():
    result = runner.invoke(app, ["run-protocol", "sphere10mm", "--sim", "--dry-run"])
    assert result.exit_code == 0, result.output
    assert "origin: x,y,z,theta = 0.0000,0.0000,0.0000,0.0000 (the simulated rig's contact point)" in result.output
    given = runner.invoke(app, ["run-protocol", "sphere10mm", "--sim", "--dry-run", "--origin", "0.5,0,0,0"])
    assert "origin: x,y,z,theta = 0.5000,0.0000,0.0000,0.0000 (from --origin)" in given.output
    tiny = runner.invoke(app, ["run-protocol", "sphere10mm", "--sim", "--dry-run", "--origin", "-9.125e-06,0,0,0"])
    assert "origin: x,y,z,theta = 0.0000,0.0000,0.0000,0.0000 (from --origin)" in tiny.output  # never e-notation


def test_a_protocol_typo_says_did_you_mean():
    for command in (["protocols", "show", "sphere10m"], ["run-protocol", "sphere10m", "--sim", "--dry-run"]):
        result = runner.invoke(app, command)
        assert result.exit_code == 1
        line = result.output.strip()
        assert line.startswith("error: no protocol named 'sphere10m' in the library; did you mean sphere10mm"), line
        assert "[-]" not in line and len(line.splitlines()) == 1


def test_protocols_show_states_the_disk_a_run_takes_compressed():
    result = runner.invoke(app, ["protocols", "show", "sphere10mm"])
    assert result.exit_code == 0, result.output
    assert "disk: about 273–319 MB on disk (camera frames, HTJ2K; 1.14 GB of raw frames at 256x256)" in result.output
    assert "with --sim: about 692–920 MB on disk" in result.output  # a simulated run file: 718 MB measured


def test_run_protocol_prints_whole_lines_with_units_when_not_on_a_terminal(tmp_path):
    """Not a terminal (a log, the main job's background collection): a full line per phase, never cut
    at 80 columns, with the time left labelled and every wrench value's unit."""
    spec = tmp_path / "tiny.toml"
    spec.write_text(
        '[protocol]\nname = "tiny"\nobject = "sphere10mm"\nsensor = "rgb"\n\n[motion]\ndepth_step_mm = 0.5\n'
        "max_depth_mm = 0.5\nshear_mm = 0.2\ntwist_deg = 1.0\nspeed_mm_s = 0.25\ntwist_speed_deg_s = 2.5\n"
        "approach_mm = 0.3\napproach_speed_mm_s = 2.0\n\n[capture]\nrate_hz = 2.5\n"
    )
    result = runner.invoke(app, ["run-protocol", str(spec), "--sim", "--out", str(tmp_path / "t.h5")])
    assert result.exit_code == 0, result.output
    lines = [line for line in result.stdout.splitlines() if line.startswith("tiny L1 ")]
    assert {line.split(":")[0] for line in lines} >= {"tiny L1 press", "tiny L1 shear", "tiny L1 twist"}, lines
    for line in lines:
        assert re.search(r"Fz +-?\d+\.\d\d N  Fx [+-]\d+\.\d\d N  Fy [+-]\d+\.\d\d N  Mz +[+-]\d+\.\d\d N·mm$", line), (
            line
        )
        assert "-0.00 " not in line, line
    assert any(len(line) > 80 for line in lines) and "…" not in result.stdout
    assert any(" left;" in line for line in lines), lines


def test_status_says_what_the_wrench_is_and_never_prints_minus_zero():
    result = runner.invoke(app, ["status", "--sim"])
    assert result.exit_code == 0, result.output
    assert "wrench as the gauge reads it (not tared): Fx +0.120 N" in result.stdout
    assert "untared raw minus session tare" not in result.stdout
    assert "-0.0000" not in result.stdout and "-0.000 " not in result.stdout


@pytest.mark.slow
def test_rig_sim_serve_removes_the_config_it_wrote(tmp_path):
    out = tmp_path / "rig-sim.toml"
    proc = subprocess.Popen([RIG, "sim", "serve", "--out", str(out)], stdout=subprocess.PIPE, text=True)
    try:
        lines = []
        for line in proc.stdout:  # waits on the process's own output, no sleeping
            lines.append(line)
            if line.startswith("serving"):
                break
        assert out.exists(), lines
        proc.send_signal(signal.SIGTERM)
        rest = proc.communicate(timeout=60)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert f"removed {out}" in rest and not out.exists()


def test_a_config_changed_after_sim_serve_wrote_it_is_left(tmp_path, capsys):
    from cli.sim_cmd import _remove_if_ours

    out = tmp_path / "rig-sim.toml"
    out.write_text("mine now\n")
    _remove_if_ours(out, "as written\n")
    assert out.read_text() == "mine now\n" and "left" in capsys.readouterr().out


def test_dataset_view_does_not_promise_to_stop_a_rig():
    from cli.console.launch import banner

    assert banner("http://127.0.0.1:8766/", live=False) == "console at http://127.0.0.1:8766/   (Ctrl-C stops)"
    assert "moves stop and the rig closes" in banner("http://127.0.0.1:8765/", live=True)
