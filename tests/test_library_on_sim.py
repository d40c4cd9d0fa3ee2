"""Every library protocol runs to the end on the built-in simulated rig with its default limits.

The texture boards press the whole gel, so at the paper's 0.4 mm steps their shear passes the
simulated rig's ±10 N Fx/Fy limit at the first level and the run aborts (as it should): their
protocol files press shallower. This holds every shipped protocol to that: run quickly (same
path, faster stages, the contact being quasi-static) and expect "complete" with the peak
wrench inside the limits.
"""

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
        result = Acquisition(rig, Plan.of(protocol), monitor_interval_s=monitor_interval_s(protocol)).run(
            out, header=header
        )
    assert result.status == "complete", f"{name}: {result.status} — {result.reason}"
    with h5py.File(out, "r") as f:
        peak_N = np.abs(f[S.WRENCH][()][:, :3]).max(axis=0)
    assert (peak_N < 0.95 * limits_N).all(), f"{name}: peak force {peak_N} N against limits {limits_N} N"
