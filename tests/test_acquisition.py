"""Protocol runs on the simulated rig, end to end, through the real drivers over ptys."""

import os
import signal
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from acquisition import schema as S
from acquisition.executor import Acquisition, ProtocolRefused
from acquisition.run_file import open_for_reading
from acquisition.run_layout import filter_ids
from cli.simulated import monitor_interval_s, simulated_rig_for
from protocols.plan import PHASES, Plan
from protocols.spec import load_protocol, parse_protocol
from rig.config import SafetyConfig

QUICK = (
    load_protocol("sphere10mm")
    .text.replace('name = "sphere10mm"', 'name = "quick"')
    .replace("max_depth_mm = 1.6", "max_depth_mm = 0.8")
    .replace("depth_step_mm = 0.4", "depth_step_mm = 0.8")
    .replace("shear_mm = 2.0", "shear_mm = 0.3")
    .replace("twist_deg = 5.0", "twist_deg = 2.0")
    .replace("speed_mm_s = 0.01", "speed_mm_s = 0.1")
    .replace("twist_speed_deg_s = 0.25", "twist_speed_deg_s = 1.0")
)


@pytest.fixture
def quick(tmp_path):
    path = tmp_path / "quick.toml"
    path.write_text(QUICK)
    return load_protocol(path)


def run(protocol, out, *, resume=False, progress=None, safety=None, on_rig=None):
    with simulated_rig_for(protocol, safety=safety) as (rig, sim, header):
        if on_rig:
            on_rig(rig, sim)
        acq = Acquisition(
            rig,
            Plan.of(protocol),
            monitor_interval_s=monitor_interval_s(protocol),
            progress=progress(sim) if progress else None,
        )
        result = acq.run(out, resume=resume, header=header)
        try:
            final = rig.positions()  # where the stages ended, read before the rig closes
        except Exception:
            final = None  # a device vanished: there is nothing to read
        return result, final


def test_complete_run_is_synchronised_and_physical(quick, tmp_path):
    out = tmp_path / "run.h5"
    result, final = run(quick, out)
    plan = Plan.of(quick)
    assert result.status == "complete" and result.frames == plan.frame_count == 33  # 8 + 4×3 + 2×4.24 + 2×2 s
    with open_for_reading(out) as f:
        assert f[S.FRAMES].shape == (plan.frame_count, 256, 256, 3) and f[S.FRAMES].chunks == (1, 256, 256, 3)
        assert f[S.STATUS][()] == b"complete"
        np.testing.assert_array_equal(f[S.CAPTURE_INDEX][:], np.arange(plan.frame_count))
        t = f[S.T_FRAME][:]
        np.testing.assert_allclose(np.diff(t), 1.0, atol=1e-9)  # 1 Hz on the rig clock, exactly
        W, P, M = f[S.WRENCH][:], f[S.POSE_COMMANDED][:], f[S.POSE_MEASURED][:]
        phase = f[S.PHASE_INDEX][:]
        assert np.abs(M[:, :3] - P[:, :3]).max() < 0.005  # the stages are where the plan says
        press = phase == PHASES.index("press")
        assert np.all(np.diff(W[press, 2]) >= -0.02) and W[press, 2][-1] > 1.0  # Fz grows with depth
        shear_y = (phase == PHASES.index("shear")) & (np.abs(P[:, 0]) < 1e-9) & (P[:, 1] > 0.1)
        assert np.all(W[shear_y, 1] > 0)  # Fy follows +y
        twist = (phase == PHASES.index("twist")) & (P[:, 3] > 1.0)
        assert np.all(W[twist, 5] > 0)  # Mz follows the twist
        assert f.attrs[S.ATTR_PROTOCOL] == QUICK and f.attrs[S.ATTR_OBJECT] == "sphere10mm"
        assert f.attrs[S.ATTR_MM_PER_PX] == pytest.approx(14.0 / 256)
        assert f[S.OBJECT_IMAGE].shape == (256, 256, 3) and f[S.REFERENCE_FRAME].shape == (256, 256, 3)
        assert "simulated rig" in f.attrs[S.ATTR_RIG_CONFIG]
        # the simulated rig's frames: the fast codec
        assert filter_ids(f[S.FRAMES])[0] == S.FRAME_CODECS[S.FAST_CODEC]["compression"]
    assert final["z"] == pytest.approx(quick.approach_mm, abs=1e-3)  # retracted at the end


def test_file_is_readable_while_it_grows(quick, tmp_path):
    out = tmp_path / "run.h5"
    seen = []

    def progress(sim):
        def check(p):
            if p.frame in (3, 9):
                with open_for_reading(out) as f:  # a second reader, SWMR
                    seen.append((p.frame, f[S.FRAMES].shape[0], f[S.STATUS][()]))
                from dataset.runs import summarize

                info = summarize(out)  # what `dataset info` prints, on the growing file
                seen.append((info.frames, info.status))

        return check

    result, _ = run(quick, out, progress=progress)
    assert result.status == "complete"
    assert seen == [(3, 3, b"running"), (3, "running"), (9, 9, b"running"), (9, "running")]


def test_force_limit_trip_retracts_and_records(tmp_path):
    # At a 1 N limit the speed envelope allows 0.03 mm/s at most (docs/safety.md): press at 0.02.
    slow = parse_protocol(QUICK.replace("speed_mm_s = 0.1", "speed_mm_s = 0.02"), "slow.toml")
    quick = slow
    out = tmp_path / "run.h5"
    safety = SafetyConfig(max_force_N=(10.0, 10.0, 1.0), max_torque_Nmm=(300, 300, 300), gel_thickness_mm=3.0)
    result, final = run(slow, out, safety=safety)
    assert result.status == "aborted" and "force limit" in result.reason and "Fz" in result.reason
    assert final["z"] == pytest.approx(quick.approach_mm, abs=1e-3)  # lifted clear
    with open_for_reading(out) as f:
        assert f[S.STATUS][()] == b"aborted" and b"force limit" in f[S.STATUS_REASON][()]
        assert 0 < f[S.FRAMES].shape[0] < Plan.of(quick).frame_count
        assert np.all(f[S.WRENCH][:, 2] < 1.5)  # everything recorded was within (or at) the limit


def test_soft_limit_refusal_before_any_motion(quick, tmp_path):
    wide = parse_protocol(QUICK.replace("shear_mm = 0.3", "shear_mm = 15.0"), "wide.toml")
    with simulated_rig_for(wide) as (rig, sim, header):
        before = {n: s.position(sim.clock.now()) for n, s in sim.world.stages.items()}
        with pytest.raises(ProtocolRefused, match=r"step \d+ \(shear, level 1\).*axis y.*soft limits"):
            Acquisition(rig, Plan.of(wide)).run(tmp_path / "wide.h5", header=header)
        assert {n: s.position(sim.clock.now()) for n, s in sim.world.stages.items()} == before
    assert not (tmp_path / "wide.h5").exists()


def interrupt_at(frame, action):
    def progress(sim):
        def hook(p):
            if p.frame == frame:
                action(sim)

        return hook

    return progress


def ctrl_c(sim):
    raise KeyboardInterrupt


def test_ctrl_c_mid_move_stops_retracts_and_closes(quick, tmp_path):
    out = tmp_path / "run.h5"
    result, final = run(quick, out, progress=interrupt_at(6, ctrl_c))
    assert result.status == "interrupted" and result.frames == 6
    assert final["z"] == pytest.approx(quick.approach_mm, abs=1e-3)
    with open_for_reading(out) as f:
        assert f[S.STATUS][()] == b"interrupted" and f[S.FRAMES].shape[0] == 6


def test_device_vanishing_mid_run_is_named_and_data_kept(quick, tmp_path):
    out = tmp_path / "run.h5"
    result, _ = run(quick, out, progress=interrupt_at(5, lambda sim: sim.servers["stages"].disconnect()))
    assert result.status == "aborted" and "device error" in result.reason and "Zaber" in result.reason, result
    assert "retract failed" in result.reason, result  # z is on the vanished chain: said, not hidden
    with open_for_reading(out) as f:
        assert f[S.STATUS][()] == b"aborted" and f[S.FRAMES].shape[0] >= 5


def test_resume_continues_without_gap_or_duplicate(quick, tmp_path):
    out = tmp_path / "run.h5"
    first, _ = run(quick, out, progress=interrupt_at(7, ctrl_c))
    assert first.status == "interrupted" and first.frames == 7
    second, _ = run(quick, out, resume=True)
    assert second.status == "complete"
    with open_for_reading(out) as f:
        np.testing.assert_array_equal(f[S.CAPTURE_INDEX][:], np.arange(Plan.of(quick).frame_count))
        assert f[S.STATUS][()] == b"complete"
        P = f[S.POSE_COMMANDED][:]
        np.testing.assert_allclose(P, [Plan.of(quick).pose_at(k) for k in range(len(P))], atol=1e-9)


def test_resume_refuses_another_protocol(quick, tmp_path):
    out = tmp_path / "run.h5"
    run(quick, out, progress=interrupt_at(3, ctrl_c))
    other = parse_protocol(QUICK.replace("twist_deg = 2.0", "twist_deg = 3.0"), "other.toml")
    from acquisition.run_file import RunFileError

    with pytest.raises(RunFileError, match="different protocol"):
        run(other, out, resume=True)


def test_resume_accepts_the_same_settings_with_other_comments(quick, tmp_path):
    """A library file whose comments changed (an upgrade, say) still resumes its runs."""
    out = tmp_path / "run.h5"
    run(quick, out, progress=interrupt_at(3, ctrl_c))
    edited = parse_protocol("# a comment added after the run started\n" + QUICK, "quick.toml")
    result, _ = run(edited, out, resume=True)
    assert result.status == "complete" and result.frames == Plan.of(quick).frame_count


def start_run(tmp_path, extra=(), speed_mm_s=0.02):
    proto = tmp_path / "slow.toml"
    proto.write_text(QUICK.replace("speed_mm_s = 0.1", f"speed_mm_s = {speed_mm_s}"))
    out = tmp_path / "run.h5"
    rig_bin = str(Path(sys.executable).parent / "rig")
    proc = subprocess.Popen(
        [rig_bin, "run-protocol", str(proto), "--sim", "--out", str(out), *extra],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    return proc, proto, out, rig_bin


def wait_for_frames(proc, out, n):
    """Until the growing run file holds ``n`` frames (bounded: ~60 s); waits on the process."""
    frames = 0
    for _ in range(600):
        try:
            proc.wait(timeout=0.1)
            break
        except subprocess.TimeoutExpired:
            pass
        if out.exists():
            try:
                with open_for_reading(out) as f:
                    frames = f[S.FRAMES].shape[0]
            except Exception:
                frames = 0  # created but not yet readable
            if frames >= n:
                break
    return frames


@pytest.mark.slow
def test_kill_9_then_resume(tmp_path):
    proc, proto, out, rig_bin = start_run(tmp_path)
    try:
        assert wait_for_frames(proc, out, 8) >= 8, "the run never got going"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    with open_for_reading(out) as f:  # readable after the crash, every flushed frame there
        n = f[S.FRAMES].shape[0]
        assert n >= 8 and f[S.STATUS][()] == b"running"
        assert np.all(f[S.WRENCH][:n, 2] > -0.05)  # tared: ≥ 0 up to the noise
    result = subprocess.run(
        [rig_bin, "run-protocol", str(proto), "--sim", "--resume", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    planned = Plan.of(load_protocol(proto)).frame_count
    with open_for_reading(out) as f:
        np.testing.assert_array_equal(f[S.CAPTURE_INDEX][:], np.arange(planned))
        assert f[S.STATUS][()] == b"complete"


@pytest.mark.slow
def test_sigterm_stops_records_and_closes(tmp_path):
    # a run four times as long: on a loaded machine the simulated run must not end before the signal
    # lands (the signal stops it after a few frames either way)
    proc, _, out, _ = start_run(tmp_path, speed_mm_s=0.005)
    try:
        assert wait_for_frames(proc, out, 4) >= 4
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=60) == 3  # interrupted
    finally:
        if proc.poll() is None:
            proc.kill()
    with h5py.File(out, "r") as f:  # closed cleanly: opens without SWMR
        assert f[S.STATUS][()] == b"interrupted" and f[S.FRAMES].shape[0] >= 4


def test_cli_dry_run_refuses_a_protocol_beyond_travel(tmp_path):
    from typer.testing import CliRunner

    from cli.rig_app import app

    wide = tmp_path / "wide.toml"
    wide.write_text(QUICK.replace("max_depth_mm = 0.8", "max_depth_mm = 8.0"))
    result = CliRunner().invoke(app, ["run-protocol", str(wide), "--sim", "--dry-run"])
    assert result.exit_code == 1 and "soft limits" in result.output and "press" in result.output
    ok = CliRunner().invoke(app, ["run-protocol", "sphere10mm", "--sim", "--dry-run"])
    assert ok.exit_code == 0 and "5783 frames" in ok.output and "nothing moved" in ok.output


def test_cli_malformed_protocol_names_file_and_key(tmp_path):
    from typer.testing import CliRunner

    from cli.rig_app import app

    bad = tmp_path / "bad.toml"
    bad.write_text(QUICK.replace('object = "sphere10mm"', "object = 7"))
    result = CliRunner().invoke(app, ["run-protocol", str(bad), "--sim"])
    assert result.exit_code == 1 and f"{bad}: [protocol.object] must be str" in result.output


@pytest.mark.parametrize("tol,expect_warnings", [(None, False), (1e-30, True)])
def test_unconverged_contact_solves_are_recorded_in_the_run_file(quick, tmp_path, tol, expect_warnings):
    """A simulated run says in its file how many contact solves stopped short of tolerance."""
    out = tmp_path / "run.h5"
    with simulated_rig_for(quick) as (rig, sim, header):
        if tol is not None:  # a tolerance below what the solver can reach
            sim.world.contact.solver.tol = tol
        acq = Acquisition(
            rig,
            Plan.of(quick),
            monitor_interval_s=monitor_interval_s(quick),
            solver_warnings=lambda: sim.world.contact.solver_warnings,
        )
        result = acq.run(out, header=header)
    assert result.status == "complete"
    with open_for_reading(out) as f:
        recorded = int(f[S.SIM_SOLVER_WARNINGS][()])
    assert recorded == result.solver_warnings
    assert (recorded > 0) == expect_warnings


def _interpolation_error(stream: np.ndarray, t: np.ndarray, wrench: np.ndarray) -> float:
    """Largest distance of the per-frame wrench from the stream interpolated at the frame times
    the way the gauge does it (rig/drivers/wrench_stream.py, WrenchBuffer.at): between the
    newest sample at or before t and the next one. Samples of one read share its stamp, and
    the newest of them at the capture is any of the group (a later read may land at the same
    instant), so the closest of the group counts."""
    worst = 0.0
    ts = stream[:, 0]
    for tk, wk in zip(t, wrench):
        i = int(np.searchsorted(ts, tk, side="right"))
        b = stream[min(i, len(ts) - 1)]
        group = np.nonzero(ts == ts[i - 1])[0]
        span = b[0] - ts[i - 1]
        w = (tk - ts[i - 1]) / span if span > 0 else 0.0
        worst = max(worst, min(np.abs(stream[j, 1:] * (1 - w) + b[1:] * w - wk).max() for j in group))
    return worst


def _check_stream(f) -> np.ndarray:
    stream, t, wrench = f[S.WRENCH_STREAM][()], f[S.T_FRAME][:], f[S.WRENCH][:]
    assert stream.shape[1] == 7 and len(stream) > 5 * len(t)  # the gauge's rate, beyond the 1 Hz frames
    assert np.all(np.diff(stream[:, 0]) >= 0)  # one read's samples share its stamp; time never goes back
    assert stream[0, 0] < t[0] and stream[-1, 0] >= t[-1]  # from the tare on, bracketing every capture
    assert _interpolation_error(stream, t, wrench) < 1e-9
    return stream


def test_full_rate_wrench_is_monotonic_and_matches_the_frames(quick, tmp_path):
    out = tmp_path / "run.h5"
    result, _ = run(quick, out)
    assert result.status == "complete"
    with open_for_reading(out) as f:
        stream = _check_stream(f)
        assert stream[:, 3].max() > 1.0  # Fz of the presses is in it
        assert f[S.WRENCH_STREAM].attrs["units"].startswith("s (rig clock), N")


def test_full_rate_wrench_survives_resume(quick, tmp_path):
    out = tmp_path / "run.h5"
    first, _ = run(quick, out, progress=interrupt_at(7, ctrl_c))
    assert first.status == "interrupted"
    with open_for_reading(out) as f:
        before = f[S.WRENCH_STREAM][()]
    second, _ = run(quick, out, resume=True)
    assert second.status == "complete"
    with open_for_reading(out) as f:
        stream = _check_stream(f)
        np.testing.assert_array_equal(stream[: len(before)], before)  # kept as it was
        t = f[S.T_FRAME][:]
        assert (stream[:, 0] > t[first.frames - 1] + 1.0).sum() > 5 * (len(t) - first.frames)  # and continued


def _noise_off_run(protocol, out, *, exact: bool):
    field_solves = []

    def setup(rig, sim):
        sim.world.spec.gauge_noise = (0.0,) * 6
        rig.camera.source.renderer._noise = None
        solve = sim.world.contact.solver.solve

        def counted(pose, **kw):
            if kw.get("fields"):
                field_solves.append(pose)
            return solve(pose, **kw)

        sim.world.contact.solver.solve = counted
        if exact:
            sim.world.solve_every_sample = True
            sim.world.contact.use_tolerance(1e-5)

    result, _ = run(protocol, out, on_rig=setup)
    assert result.status == "complete"
    with open_for_reading(out) as f:
        return f[S.WRENCH][:], f[S.FRAMES][:].astype(float), len(field_solves)


@pytest.mark.realtime  # the simulated rig's threads: starved, its gauge samples age past the guard
@pytest.mark.slow
def test_captures_share_the_gauges_solve_and_stay_within_the_stated_error_of_the_exact_path(quick, tmp_path):
    """Each capture renders the contact the gauge solved at that instant (the camera adds
    only the fields), and the run stays within its stated error of the exact path (every
    gauge sample solved at its own time, tolerance 1e-5), noise off: one count of the
    FT300's wire format (0.01 N, 1 N·mm), 1 grey level RMS (docs/benchmarks.md, "Simulated
    run", has the measured figures)."""
    w_fast, f_fast, camera_solves = _noise_off_run(quick, tmp_path / "fast.h5", exact=False)
    w_exact, f_exact, _ = _noise_off_run(quick, tmp_path / "exact.h5", exact=True)
    assert camera_solves <= 3  # the discarded first frames and the reference frame, above the gel
    assert np.abs(w_exact[:, 2]).max() > 1.0 and np.abs(w_exact[:, 1]).max() > 0.1  # pressed and sheared
    err = np.abs(w_fast - w_exact)
    assert err[:, :3].max() <= 0.01 + 1e-9 and err[:, 3:].max() <= 1.0 + 1e-9
    assert np.sqrt(np.mean((f_fast - f_exact) ** 2)) < 1.0
