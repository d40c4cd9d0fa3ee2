"""Every library protocol runs to the end on the built-in simulated rig inside its limits.

The texture boards press the whole gel, the paper's 0.4 mm steps to 1.6 mm: their loads (85 N,
shear 17 N) are far beyond a sphere's, so their protocol files declare [limits] scaled from the
contact area and the gel's stiffness (docs/protocols.md, "Texture boards"), which the simulated
rig adopts. This holds every shipped protocol to its paper-like sequence: run quickly (same
path, faster stages, the contact being quasi-static) and expect "complete" with the peak wrench
inside the limits it ran under — and a rig whose own [safety] allows less refuses a board.
"""

import dataclasses
import re

import h5py
import numpy as np
import pytest

from acquisition import schema as S
from acquisition.executor import Acquisition
from cli.simulated import monitor_interval_s, simulated_rig_for
from protocols.plan import Plan
from protocols.spec import load_protocol, protocol_names


def _fast(name: str, tmp_path):
    """100× the protocol's speeds, inside the speed envelope of the simulated rig (docs/safety.md:
    ~1.2 mm/s in contact at its 40 N limit), with a capture every 5 s instead of every 1 s to
    keep the frame count of a quick run."""
    text = load_protocol(name).text
    text = re.sub(r"(?m)^speed_mm_s = [0-9.]+", "speed_mm_s = 1.0", text)
    text = re.sub(r"(?m)^twist_speed_deg_s = [0-9.]+", "twist_speed_deg_s = 5.0", text)
    text = re.sub(r"(?m)^rate_hz = [0-9.]+", "rate_hz = 0.2", text)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return load_protocol(path)


@pytest.mark.parametrize("name", sorted(protocol_names()))
def test_library_protocol_completes_within_the_simulated_rigs_limits(name, tmp_path):
    protocol = _fast(name, tmp_path)
    out = tmp_path / f"{name}.h5"
    with simulated_rig_for(protocol) as (rig, _sim, header):
        limits_N = np.asarray(rig.config.safety.max_force_N, dtype=float)
        if protocol.max_force_N is not None:  # a board: run at the paper's depth under its own [limits]
            assert protocol.levels[-1] == pytest.approx(1.6) and limits_N.tolist() == list(protocol.max_force_N)
        result = Acquisition(rig, Plan.of(protocol), monitor_interval_s=monitor_interval_s(protocol)).run(
            out, header=header
        )
    assert result.status == "complete", f"{name}: {result.status} — {result.reason}"
    with h5py.File(out, "r") as f:
        peak_N = np.abs(f[S.WRENCH][()][:, :3]).max(axis=0)
    assert (peak_N < 0.95 * limits_N).all(), f"{name}: peak force {peak_N} N against limits {limits_N} N"


def test_a_rig_whose_safety_allows_less_than_a_boards_limits_refuses_it_before_moving(tmp_path):
    """The simulated rig's own limits (Fz 40 N) are below woven's 111 N: the run is refused in
    one line naming the component, both values and the way out, and no file is written."""
    from acquisition.executor import ProtocolRefused

    protocol = _fast("woven", tmp_path)
    with simulated_rig_for(protocol) as (rig, _sim, _header):
        own = rig.config.safety
    tight = dataclasses.replace(own, max_force_N=(10.0, 10.0, 40.0), max_torque_Nmm=(300.0, 300.0, 200.0))
    out = tmp_path / "woven.h5"
    with simulated_rig_for(protocol, safety=tight) as (rig, sim, header):
        z0 = rig.axes["z"].position()
        with pytest.raises(ProtocolRefused, match=r"woven reaches \|Fx\| up to 23 N .* allows \(10 N\).*nothing moved"):
            Acquisition(rig, Plan.of(protocol), monitor_interval_s=monitor_interval_s(protocol)).run(out, header=header)
        assert rig.axes["z"].position() == z0
    assert not out.exists()


def test_dry_runs_of_a_board_pass_on_the_simulated_rig_and_are_refused_on_a_rig_set_up_for_spheres():
    """`--sim --dry-run` checks a board against the simulated rig as its run would be (its [limits]
    adopted); against docs/rig.example.toml (Fx limit 5 N) the dry run refuses in one line."""
    from pathlib import Path

    from typer.testing import CliRunner

    from cli.rig_app import app

    sim = CliRunner().invoke(app, ["run-protocol", "ridged", "--sim", "--dry-run"])
    assert sim.exit_code == 0, sim.output
    assert "dry run: ridged fits" in sim.output
    example = Path(__file__).resolve().parents[1] / "docs" / "rig.example.toml"
    shown = CliRunner().invoke(app, ["protocols", "show", "ridged"])
    assert "limits: |Fx| ≤ 23, |Fy| ≤ 23, |Fz| ≤ 113 N" in shown.output, shown.output
    refused = CliRunner().invoke(app, ["run-protocol", "ridged", "--config", str(example), "--dry-run"])
    assert refused.exit_code == 1, refused.output
    errors = [line for line in refused.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "ridged reaches |Fx| up to 23 N" in errors[0] and "allows (5 N)" in errors[0], errors
    assert "Traceback" not in refused.output
