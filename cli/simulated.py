"""The built-in simulated rig set up for a protocol run.

Discrete-event time: simulated time advances only when the executor waits, so every
capture happens exactly on schedule however long a frame takes to make, and a run
takes as long as its work. The devices still talk to the drivers over ptys.
"""

from __future__ import annotations

import contextlib
import dataclasses
import re

from acquisition.schema import FAST_CODEC, RIG_CONFIG_MARK
from rig.clock import ManualClock
from rig.config import SafetyConfig
from rig.rig import Rig
from rig.sim.rig_sim import SimulatedRig
from sensor_sim.profile import SensorProfile, default_profile
from sensor_sim.world_contact import ElastomerContact

GAUGE_RATE_HZ = 10.0  # simulated time; the run samples the wrench at the capture rate


@contextlib.contextmanager
def simulated_rig_for(
    protocol, *, safety: SafetyConfig | None = None, transport: str = "pty", profile: SensorProfile | None = None
):
    """Yield (rig, simulated rig, run-file header) for ``protocol`` on the simulated rig with the
    sensor ``profile`` (default: the shipped GelSight Mini), whose name and hash the run file keeps.
    The simulated rig's force limits are ``safety``'s, else the protocol's [limits], else its own."""
    clock = ManualClock()
    profile = profile or default_profile()
    with SimulatedRig(
        clock,
        indenter=protocol.object,
        sensor_kind=protocol.sensor,
        gauge_rate_hz=GAUGE_RATE_HZ,
        transport=transport,
        profile=profile,
    ) as simulated:
        simulated.triggered_camera = True
        cfg = simulated.config()
        config_text = simulated.config_toml()
        if safety is not None:
            cfg = dataclasses.replace(cfg, safety=safety)
        elif protocol.max_force_N is not None:
            cfg = with_protocol_limits(cfg, protocol)
            config_text = _with_limits(config_text, _limits(protocol))  # the run file records the limits it ran under
        contact = simulated.world.contact
        assert isinstance(contact, ElastomerContact) and cfg.camera is not None  # the simulated rig's gel and camera
        geometry = contact.solver.geometry
        header = {
            "rig_config": RIG_CONFIG_MARK + "\n" + config_text,
            "mm_per_px": geometry.width_mm / cfg.camera.width,
            "sensor_profile": profile.record(),
            # the simulator's frames are mostly sensor noise, written ~150 a second: the fast codec
            # (acquisition/schema.py; docs/benchmarks.md, "Run-file storage")
            "frame_codec": FAST_CODEC,
        }
        with Rig.open(cfg, clock, camera=True, sim=simulated, indenter=protocol.object) as rig:
            yield rig, simulated, header


def _limits(protocol) -> dict[str, tuple[float, float, float]]:
    return {"max_force_N": protocol.max_force_N, "max_torque_Nmm": protocol.max_torque_Nmm}


def with_protocol_limits(cfg, protocol):
    """The simulated rig's config for ``protocol``: the simulated rig stands for one set up for it,
    so the protocol's [limits] (a board's loads, docs/protocols.md) are its [safety]'s; unchanged
    for a protocol that declares none."""
    if protocol.max_force_N is None or cfg.safety is None:
        return cfg
    return dataclasses.replace(cfg, safety=dataclasses.replace(cfg.safety, **_limits(protocol)))


def _with_limits(text: str, limits: dict[str, tuple[float, float, float]]) -> str:
    """The simulated rig's config text with its [safety] force and torque limits replaced."""
    for key, values in limits.items():
        line = f"{key} = [{', '.join(repr(float(v)) for v in values)}]  # the protocol's [limits]"
        text, n = re.subn(rf"(?m)^{key} = \[[^\]]*\]", line, text)
        if n != 1:
            raise AssertionError(f"the simulated rig's config has {n} lines for {key}, expected 1")
    return text


def monitor_interval_s(protocol) -> float:
    """Safety checks with every capture: 10 µm of travel at 0.01 mm/s and 1 Hz."""
    return 1.0 / protocol.capture_hz
