"""A simulated device as the simulated rig serves it, and the built-in gauges' simulators.

A registry row's ``simulator`` (rig/config/registry.py) names a function
``simulate(world, clock, *, transport, rate_hz) -> ServedDevice``: it builds the device
model on the shared ``SimWorld``, serves it, and says which config keys point at it. The
simulated rig writes ``driver = <kind>`` plus those keys into its config, so the
drivers open the simulators exactly as they open hardware.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from rig.clock import Clock
from rig.sim.ft300_sim import Ft300Sim
from rig.sim.link import DeviceModel, SimServer
from rig.sim.m8128_sim import M8128Sim
from rig.sim.world import SimWorld

NETFT_MIN_RATE_HZ = 1000.0  # a Net F/T's RDT rate starts here; slower rates are set on its web page


@dataclass
class ServedDevice:
    model: Any  # the device model (tests reach in: faults, counters)
    keys: dict[str, Any]  # the config section's keys that point at it (port, ...)
    servers: dict[str, SimServer] = field(default_factory=dict)  # byte-stream servers, listed by `rig sim serve`
    close: Callable[[], None] = lambda: None


def serve_bytes(model: DeviceModel, clock: Clock, *, transport: str, name: str, **keys: Any) -> ServedDevice:
    """A byte-speaking model behind one pty or loopback TCP port: ``port`` plus ``keys``.

    On a discrete-event clock a streaming model emits on each advance, so a sample
    stamped now is from now.
    """
    schedule = getattr(model, "schedule", None)
    if schedule is not None:
        schedule.report_on_advance = hasattr(clock, "add_listener")
    server = SimServer(model, clock, transport=transport, name=name)
    return ServedDevice(model, {"port": server.url, **keys}, {"gauge": server}, server.close)


def simulate_ft300(world: SimWorld, clock: Clock, *, transport: str, rate_hz: float) -> ServedDevice:
    return serve_bytes(Ft300Sim(world, rate_hz=rate_hz), clock, transport=transport, name="ft300", device_id=9)


def simulate_m8128(world: SimWorld, clock: Clock, *, transport: str, rate_hz: float) -> ServedDevice:
    return serve_bytes(M8128Sim(world, rate_hz=rate_hz), clock, transport=transport, name="m8128")


def simulate_ati_netft(world: SimWorld, clock: Clock, *, transport: str, rate_hz: float) -> ServedDevice:
    """UDP RDT and HTTP on loopback whatever ``transport`` says: the box has no serial line."""
    from rig.sim.ati_netft_sim import AtiNetFtSim

    sim = AtiNetFtSim(world, rate_hz=max(rate_hz, NETFT_MIN_RATE_HZ))
    return ServedDevice(sim, {"port": sim.host, "rdt_port": sim.rdt_port, "http_port": sim.http_port}, close=sim.close)
