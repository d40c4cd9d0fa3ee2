"""The one guarded motion path: every move happens in a
motion session that arms the limits, checks the wrench after the last axis went idle,
and stops and lifts on any way out: return, exception, SIGINT, SIGTERM, SIGHUP."""

import ast
import dataclasses
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from test_acquisition import QUICK
from typer.testing import CliRunner

import rig.rig as rig_module
from acquisition import schema as S
from acquisition.executor import Acquisition
from acquisition.run_file import RunWriter, open_for_reading
from cli.rig_app import app
from cli.simulated import monitor_interval_s, simulated_rig_for
from protocols.plan import Plan
from protocols.spec import load_protocol
from rig.clock import ManualClock
from rig.errors import ForceLimitExceeded, SafetyError
from rig.motion import AXIS_MOTION_METHODS, SESSION_MODULES, active_sessions
from rig.rig import Rig
from rig.sim.rig_sim import SimulatedRig

ROOT = Path(__file__).resolve().parents[1]
RIG_BIN = str(Path(sys.executable).parent / "rig")


# -- structure: the rig moves only inside a session ---------------------------------------

# The layers below the rig implement the motion methods (drivers, simulators, transports);
# everything above may reach an axis only through rig/motion.py.
BELOW_THE_RIG = ("rig/drivers", "rig/sim", "rig/transport")


def test_no_module_but_the_motion_module_calls_an_axis_motion_method():
    offenders = []
    for package in ("rig", "acquisition", "protocols", "dataset", "model", "bench", "scripts"):
        for path in sorted((ROOT / package).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel in SESSION_MODULES or rel.startswith(BELOW_THE_RIG):
                continue
            for node in ast.walk(ast.parse(path.read_text(), rel)):
                if (
                    isinstance(node, ast.Call)
                    and isinstance(node.func, ast.Attribute)
                    and node.func.attr in AXIS_MOTION_METHODS
                ):
                    offenders.append(f"{rel}:{node.lineno} calls .{node.func.attr}()")
    assert offenders == [], "motion outside the motion session (rig/motion.py):\n" + "\n".join(offenders)


def test_the_rig_itself_has_no_way_to_move():
    for name in ("move", "jog", "home", "start_move", "monitor"):
        assert not hasattr(Rig, name), f"Rig.{name} would be a motion path outside the session"


@pytest.fixture
def manual_rig():
    clock = ManualClock()
    with SimulatedRig(clock) as sim, Rig.open(sim.config(with_camera=False), clock, axes=("x", "z")) as rig:
        rig.gauge.stop_stream()  # a manual clock emits no stream on its own: poll instead
        yield rig, sim


def test_a_session_cannot_be_reused_nested_or_outlived(manual_rig):
    rig, _ = manual_rig
    with rig.motion("first") as m:
        with pytest.raises(SafetyError, match="already open"):
            rig.motion("second").__enter__()
        m.move({"x": 0.1}, 1.0)
    with pytest.raises(SafetyError, match="not open"):
        m.move({"x": 0.2}, 1.0)
    with pytest.raises(SafetyError, match="already used"):
        with m:
            pass


@pytest.fixture
def guarded_axes(monkeypatch):
    """Every axis the rig opens fails its motion methods unless a session on its rig is open;
    returns the (axis, method) calls seen, so a test knows the check ran."""
    calls = []
    original_open_axis = rig_module.open_axis

    def open_checked_axis(cfg, pool):
        axis = original_open_axis(cfg, pool)
        for method in AXIS_MOTION_METHODS:
            real = getattr(axis, method)

            def checked(*args, _real=real, _method=method, **kwargs):
                sessions = [s for s in active_sessions() if axis in s.rig.axes.values()]
                assert sessions, f"{axis.name}.{_method}() called outside a motion session"
                calls.append((axis.name, _method))
                return _real(*args, **kwargs)

            setattr(axis, method, checked)
        return axis

    monkeypatch.setattr(rig_module, "open_axis", open_checked_axis)
    return calls


@pytest.mark.slow
@pytest.mark.parametrize(
    "args, stdin, expected",
    [
        (["jog", "--axis", "z", "--step", "-0.5"], None, {("z", "move_to")}),
        (["jog", "--axis", "x", "--to", "1.5"], None, {("x", "move_to")}),
        (["jog", "--axis", "y"], "++-q", {("y", "move_to")}),
        (["home", "--axis", "z", "--axis", "theta"], None, {("z", "home"), ("theta", "home")}),
        (["find-contact", "--speed", "2"], None, {("z", "move_to")}),
        (["check-axes"], None, {("z", "move_to"), ("x", "move_to"), ("y", "move_to"), ("theta", "move_to")}),
    ],
)
def test_every_moving_command_goes_through_the_session(guarded_axes, args, stdin, expected, monkeypatch):
    monkeypatch.setattr("cli.rig_app.stdin_is_terminal", lambda: True)  # the keys stand in for a terminal's
    result = CliRunner().invoke(app, [*args, "--sim"], input=stdin)
    assert result.exit_code == 0, result.output
    assert set(guarded_axes) == expected


def test_pendant_jogging_goes_through_the_session(guarded_axes):
    from test_spacemouse import FakeHid

    from cli.interactive import jog_with_pendant
    from rig.clock import ScaledClock
    from rig.drivers.spacemouse import SpaceMouse

    # Cap pulled up for one poll, released, then button 1 (quit): the recorded reports of test_spacemouse.
    reports = [bytes.fromhex("01 0000 0000 a2fe"), bytes.fromhex("01 0000 0000 0000"), bytes.fromhex("03 01 00")]

    class OneReportPerPoll(FakeHid):
        def read(self, size, timeout_ms=0):
            return super().read(size) if timeout_ms else []

    with SimulatedRig(ScaledClock(20.0)) as sim, Rig.open(sim.config(), sim.clock, axes=("z",)) as rig:
        with rig.motion("jog") as m:
            jog_with_pendant(m, "z", 0.1, None, pendant=SpaceMouse(OneReportPerPoll(reports)))
    assert guarded_axes == [("z", "move_to")]


@pytest.mark.slow
def test_a_protocol_run_goes_through_the_session(guarded_axes, tmp_path):
    proto = tmp_path / "quick.toml"
    proto.write_text(QUICK)
    out = tmp_path / "run.h5"
    result = CliRunner().invoke(app, ["run-protocol", str(proto), "--sim", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert {axis for axis, _ in guarded_axes} == {"x", "y", "z", "theta"}


# -- finding 3: the wrench after the last axis went idle must pass -------------------------


class LaggingGauge:
    """The real gauge driver, but ``read`` answers with the sample of the previous read,
    stamped when it was measured: what a stream gives when its newest sample predates the
    end of the travel. ``read_fresh`` keeps its promise (measured after the call)."""

    def __init__(self, gauge):
        self._gauge = gauge
        self._previous = None

    def read(self):
        sample = self._gauge.read()
        previous, self._previous = self._previous or sample, sample
        return previous

    def __getattr__(self, name):
        return getattr(self._gauge, name)


def pressed_rig(clock, sim):
    """z pressed 1 mm into the gel, the Fz limit set just above that load, the gauge
    lagging one poll; polls 0.5 s apart so that a 0.2 mm step ends within one. The contact is
    configured far softer than it is (0.5 N/mm), so that the bounded command (rig/bounded.py)
    lets the whole step go out and only the check after it can see the overload."""
    cfg = sim.config(with_camera=False)
    cfg = dataclasses.replace(cfg, safety=dataclasses.replace(cfg.safety, poll_s=0.5, stiffness_N_per_mm=0.5))
    rig = Rig.open(cfg, clock, axes=("z",))
    rig.gauge.stop_stream()
    rig.gauge = LaggingGauge(rig.gauge)
    rig.tare(10)
    with rig.motion("press") as m:
        m.move({"z": -1.0}, 1.0)
    fz_N = rig.gauge.read_fresh().fz_N
    rig.guard.limits[2] = fz_N + 0.2
    return rig


@pytest.mark.parametrize("step_mm", [-0.2, -0.25, -0.3])
def test_an_overload_in_the_last_poll_before_idle_trips(step_mm):
    clock = ManualClock()
    with SimulatedRig(clock) as sim:
        rig = pressed_rig(clock, sim)
        try:
            limit_N = rig.guard.limits[2]
            with pytest.raises(ForceLimitExceeded, match="Fz") as err:
                with rig.motion("jog") as m:
                    m.jog("z", step=step_mm, speed=1.0)
            assert err.value.value > limit_N
            assert rig.axes["z"].position() > 0.0  # lifted clear of the gel (its surface is z = 0)
        finally:
            rig.close()
        assert abs(sim.world.true_wrench()[2]) < 0.05


@pytest.mark.parametrize("step", ["-0.2", "-0.25", "-0.3"])
def test_the_cli_exits_non_zero_on_an_end_of_move_overload(monkeypatch, step):
    import contextlib

    import cli.session as session

    clock = ManualClock()
    with SimulatedRig(clock) as sim:

        @contextlib.contextmanager
        def open_pressed(*_args, **_kwargs):
            rig = pressed_rig(clock, sim)
            try:
                yield rig
            finally:
                rig.close()

        monkeypatch.setattr(session, "open_rig", open_pressed)
        result = CliRunner().invoke(app, ["jog", "--axis", "z", "--step", step, "--speed", "1"])
    assert result.exit_code == 1, result.output
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    # read over the limit, or predicted to pass it before a stop could act (docs/safety.md)
    assert (
        len(errors) == 1 and "Fz" in errors[0] and ("exceeds the limit" in errors[0] or "over the limit" in errors[0])
    )
    assert "Traceback" not in result.output


# -- finding 4: an exception that is not the rig's own still stops and retracts -----------


@pytest.fixture
def quick(tmp_path):
    path = tmp_path / "quick.toml"
    path.write_text(QUICK)
    return load_protocol(path)


def run_with_fault(protocol, out, arm):
    """Run ``protocol`` with ``arm(rig, progress_frame)`` called at every frame; returns
    the error raised, the stage positions and whether anything still moved afterwards."""
    with simulated_rig_for(protocol) as (rig, sim, header):
        acq = Acquisition(
            rig,
            Plan.of(protocol),
            monitor_interval_s=monitor_interval_s(protocol),
            progress=lambda p: arm(rig, p.frame),
        )
        with pytest.raises(ValueError) as err:
            acq.run(out, header=header)
        busy = [n for n, s in sim.world.stages.items() if s.busy(sim.clock.now())]
        return err.value, rig.positions(), busy, sim.world.true_wrench()


def test_a_drivers_value_error_mid_run_stops_retracts_and_is_recorded(quick, tmp_path):
    out = tmp_path / "run.h5"

    def arm(rig, frame):
        if frame == 10:  # pressed into the gel, x and y about to shear

            def broken_status():
                raise ValueError("not enough values to unpack (expected 2, got 1)")

            rig.axes["x"].status = broken_status

    error, final, busy, wrench = run_with_fault(quick, out, arm)
    assert "not enough values" in str(error)
    assert busy == []
    assert final["z"] == pytest.approx(quick.approach_mm, abs=1e-3)  # lifted clear
    assert abs(wrench[2]) < 0.01
    with open_for_reading(out) as f:
        assert f[S.STATUS][()] == b"aborted"
        reason = f[S.STATUS_REASON][()].decode()
        assert reason.startswith("aborted: ValueError: not enough values to unpack (expected 2, got 1); ")
        assert "z lifted from -0.800 to 1.000 mm (loaded when protocol stopped)" in reason  # what the stop did


def test_a_writers_value_error_mid_run_stops_retracts_and_is_recorded(quick, tmp_path, monkeypatch):
    out = tmp_path / "run.h5"
    real_append = RunWriter.append

    def append(self, image, **rows):
        if self.n == 6:
            raise ValueError("could not broadcast input array from shape (3,) into shape (4,)")
        return real_append(self, image, **rows)

    monkeypatch.setattr(RunWriter, "append", append)
    error, final, busy, wrench = run_with_fault(quick, out, lambda rig, frame: None)
    assert "could not broadcast" in str(error)
    assert busy == []
    assert final["z"] == pytest.approx(quick.approach_mm, abs=1e-3)
    with open_for_reading(out) as f:
        assert f[S.STATUS][()] == b"aborted" and f[S.FRAMES].shape[0] == 6
        assert b"ValueError: could not broadcast" in f[S.STATUS_REASON][()]


# -- finding 1: SIGTERM and SIGHUP mid-move, from another process ------------------------


class ZaberLog:
    """Every command the simulated Zaber chain executes: (monotonic s, axis, command)."""

    def __init__(self, sim):
        self.entries = []
        real = sim.zaber._execute

        def execute(dev, axis, words, now_s):
            self.entries.append((time.monotonic(), dev.stage.name, " ".join(words)))
            return real(dev, axis, words, now_s)

        sim.zaber._execute = execute

    def polls_between_signal_and_stop(self, axis: str, t_signal: float) -> int:
        polls = 0
        for t, name, command in self.entries:
            if t < t_signal or name != axis:
                continue
            if command == "stop":
                return polls
            if command == "get pos":
                polls += 1
        raise AssertionError(f"{axis} was never stopped after the signal")


def lines_of(stream) -> "queue.Queue[str]":
    lines: queue.Queue[str] = queue.Queue()

    def pump():
        for line in stream:
            lines.put(line)

    threading.Thread(target=pump, daemon=True).start()
    return lines


def wait_for_line(lines, prefix_in: str, deadline_s: float = 30.0) -> str:
    end = time.monotonic() + deadline_s
    seen = []
    while time.monotonic() < end:
        try:
            line = lines.get(timeout=end - time.monotonic())
        except queue.Empty:
            break
        seen.append(line)
        if prefix_in in line:
            return line
    raise AssertionError(f"no line with {prefix_in!r} within {deadline_s} s; saw {seen}")


@pytest.mark.slow
@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
@pytest.mark.parametrize(
    "command, moving_line",
    [
        (["jog", "--axis", "z", "--to", "-3"], "z: moving to -3.0000 mm"),
        (["home", "--axis", "z"], "z: homing"),
        (["find-contact"], "z: moving to"),
    ],
)
def test_a_signal_mid_move_stops_every_axis_and_leaves_the_gauge_usable(tmp_path, signame, command, moving_line):
    with SimulatedRig(transport="pty") as sim:
        cfg = tmp_path / "rig-sim.toml"
        cfg.write_text(sim.config_toml(with_camera=False))
        log = ZaberLog(sim)
        proc = subprocess.Popen(
            [RIG_BIN, *command, "--config", str(cfg)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        try:
            wait_for_line(lines_of(proc.stderr), moving_line)
            assert sim.world.stages["z"].busy(sim.clock.now()), "the command said it moves, but z is idle"
            t_signal = time.monotonic()
            proc.send_signal(getattr(signal, signame))
            rc = proc.wait(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        err = proc.stderr.read() if proc.stderr else ""
        assert rc == 128 + getattr(signal, signame), (rc, err)
        assert "Traceback" not in err
        assert not any(s.busy(sim.clock.now()) for s in sim.world.stages.values())
        # Stopped at once: no control period began after the signal (at most the poll in flight).
        assert log.polls_between_signal_and_stop("z", t_signal) <= 1
        status = subprocess.run([RIG_BIN, "status", "--config", str(cfg)], capture_output=True, text=True, timeout=60)
        assert status.returncode == 0, status.stderr
        assert "Fz" in status.stdout


@pytest.mark.slow
def test_sighup_to_a_protocol_run_is_recorded_by_name(tmp_path):
    from test_acquisition import start_run, wait_for_frames

    proc, _, out, _ = start_run(tmp_path)
    try:
        assert wait_for_frames(proc, out, 4) >= 4
        proc.send_signal(signal.SIGHUP)
        assert proc.wait(timeout=60) == 3  # run-protocol's "interrupted" exit code
    finally:
        if proc.poll() is None:
            proc.kill()
    with open_for_reading(out) as f:
        assert f[S.STATUS][()] == b"interrupted"
        reason = f[S.STATUS_REASON][()].decode()
        assert reason.startswith("interrupted (SIGHUP); resume with --resume; z lifted from ")  # and what the stop did
