"""The real command line against `rig sim serve`: signals at any moment of a command while z is
pressed, a rig that was never tared, and a dry run that refuses what the run refuses
(docs/safety.md). z and the load are read back with `rig status`, as a user would."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from processes import stop

from rig.rig_state import state_path

RIG = str(Path(sys.executable).parent / "rig")
pytestmark = pytest.mark.realtime  # signals at moments of real time, rates of real samples
SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")


def _rig(*args, timeout=120):
    return subprocess.run([RIG, *args], capture_output=True, text=True, timeout=timeout)


def _z_and_fz(cfg: Path) -> tuple[float, float]:
    out = _rig("status", "--config", str(cfg))
    assert out.returncode == 0, out.stderr
    row = next(line for line in out.stdout.splitlines() if line.replace("│", " ").split()[:1] == ["z"])
    z = float(re.search(r"[-+]\d+\.\d+", row).group())
    fz = float(re.search(r"Fz ([-+]\d+\.\d+) N", out.stdout).group(1))
    return z, fz


def _wait_at_most(proc: subprocess.Popen, seconds: float) -> None:
    """Let ``proc`` run ``seconds`` of real time (or until it ends)."""
    try:
        proc.wait(timeout=seconds)
    except subprocess.TimeoutExpired:
        pass


def _holds_signals(pid: int) -> bool:
    """Whether the process catches SIGTERM: a moving command's first instruction has run
    (rig/early_signals.py; Python itself catches only SIGINT before it)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    caught = int(re.search(r"^SigCgt:\s*([0-9a-f]+)$", status, re.M).group(1), 16)
    return bool(caught >> (signal.SIGTERM - 1) & 1)


def _wait_first_instruction(proc: subprocess.Popen) -> None:
    """Until ``proc`` has run its first instruction (bounded: 30 s). Before it, a signal meets
    Python's own start-up, which no code of the project can see (docs/safety.md)."""
    for _ in range(15000):
        if _holds_signals(proc.pid):
            return
        _wait_at_most(proc, 0.002)
        assert proc.poll() is None, "the command ended before its first instruction"
    raise AssertionError("the command did not reach its first instruction in 30 s")


def _state(cfg: Path) -> dict:
    path = state_path(str(cfg), "simulated rig")
    return json.loads(path.read_text()) if path.exists() else {}


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """One `rig sim serve` (its own process, real time) for the module; its config file."""
    folder = tmp_path_factory.mktemp("served")
    cfg = folder / "sim.toml"
    server = subprocess.Popen(
        [RIG, "sim", "serve", "--out", str(cfg), "--transport", "tcp"], stdout=subprocess.PIPE, text=True
    )
    try:
        for line in server.stdout:
            if line.startswith("serving"):
                break
        yield cfg
    finally:
        stop(server)


@pytest.mark.timeout(900)
@pytest.mark.slow
@settings(max_examples=6, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(at_s=st.floats(0.05, 0.5), name=st.sampled_from(SIGNALS))
def test_a_signal_at_any_moment_of_a_command_lifts_z_when_pressed(served, at_s, name):
    """From the command's first instruction (imports, the rig opening, the session opening) a
    SIGINT, SIGTERM or SIGHUP stops it and lifts z off the gel, and the exit status names it."""
    cfg = served
    if "tare" not in _state(cfg):
        assert _rig("zero", "--config", str(cfg)).returncode == 0
    pressed = _rig("jog", "--axis", "z", "--to", "-0.6", "--config", str(cfg))
    assert pressed.returncode == 0, pressed.stderr
    surface = _state(cfg)["surfaces"][""]["z_mm"]
    unloaded = _state(cfg)["tare"]["raw"][2]
    z, fz = _z_and_fz(cfg)
    assert z < surface and fz - unloaded > 0.5  # pressed
    jog = subprocess.Popen(
        [RIG, "jog", "--axis", "z", "--step", "-0.02", "--speed", "0.01", "--config", str(cfg)],
        stderr=subprocess.PIPE,
        text=True,
    )
    _wait_first_instruction(jog)  # on a loaded machine Python's own start-up can take longer than 50 ms
    _wait_at_most(jog, at_s)  # the moment, in real time after the first instruction
    jog.send_signal(getattr(signal, name))
    _, err = jog.communicate(timeout=60)
    assert jog.returncode == 128 + getattr(signal, name), f"{name} at {at_s:.3f} s: rc {jog.returncode}\n{err}"
    z, fz = _z_and_fz(cfg)
    assert z > surface + 0.3, f"{name} at {at_s:.3f} s: z = {z} mm, surface {surface} mm\n{err}"
    assert abs(fz - unloaded) < 0.05, f"{name} at {at_s:.3f} s: Fz {fz} N raw, unloaded {unloaded} N\n{err}"


@pytest.mark.timeout(600)
@pytest.mark.slow
@pytest.mark.parametrize("tare", ["kept from the session's start", "none at all"])
def test_without_rig_zero_a_signalled_press_lifts_just_clear_and_the_rig_moves_again(tmp_path, tare):
    """The gauge's constant offset (0.35 N on the simulated FT300) is not a load: a press signalled
    without any `rig zero` lifts to just above the gel, not 5 mm up, and the next jog moves."""
    cfg = tmp_path / "sim.toml"
    server = subprocess.Popen(
        [RIG, "sim", "serve", "--out", str(cfg), "--transport", "tcp"], stdout=subprocess.PIPE, text=True
    )
    try:
        for line in server.stdout:
            if line.startswith("serving"):
                break
        first = _rig("jog", "--axis", "z", "--to", "-0.8", "--config", str(cfg))
        assert first.returncode == 0 and "first contact" in first.stderr, first.stderr
        state = _state(cfg)
        surface = state["surfaces"][""]["z_mm"]
        assert "tare" in state  # the session's start, confirmed unloaded by its first contact
        if tare == "none at all":
            del state["tare"]
            state_path(str(cfg), "simulated rig").write_text(json.dumps(state))
        jog = subprocess.Popen(
            [RIG, "jog", "--axis", "z", "--to", "-1.2", "--speed", "0.05", "--config", str(cfg)],
            stderr=subprocess.PIPE,
            text=True,
        )
        for line in jog.stderr:
            if "moving to" in line:
                break
        _wait_at_most(jog, 0.5)  # pressing on
        jog.send_signal(signal.SIGTERM)
        _, err = jog.communicate(timeout=120)
        assert jog.returncode == 143, err
        assert "lift it by hand" not in err and "open-loop" not in err, err
        z, _ = _z_and_fz(cfg)
        assert surface + 0.3 < z < surface + 2.0, f"z = {z} mm after the lift (surface {surface} mm)\n{err}"
        again = _rig("jog", "--axis", "z", "--step", "-0.1", "--config", str(cfg))
        assert again.returncode == 0, again.stderr  # never "may have started pressed" in the air
    finally:
        stop(server)


@pytest.mark.timeout(300)
def test_a_dry_run_refuses_what_the_run_refuses(served, tmp_path):
    """The speed envelope of the rig the command names: measured on it by the dry run as by the
    run, so a step the run would refuse is refused before anything is started."""
    cfg = served
    args = ["run-protocol", "sphere10mm", "--config", str(cfg), "--set", "motion.speed_mm_s=0.4"]
    dry = _rig(*args, "--dry-run")
    assert dry.returncode != 0 and "faster than the speed envelope" in dry.stderr, dry.stdout + dry.stderr
    run = _rig(*args, "--out", str(tmp_path / "run.h5"))
    assert run.returncode != 0 and not (tmp_path / "run.h5").exists()
    refusal = re.search(r"protocol step \d+ \(press, level \d+\): z at 0.4 mm/s is faster", run.stderr)
    assert refusal and refusal.group() in dry.stderr, (run.stderr, dry.stderr)
    fits = _rig("run-protocol", "sphere10mm", "--config", str(cfg), "--dry-run")
    assert fits.returncode == 0 and "speed envelope measured on the rig now" in fits.stdout, fits.stderr
