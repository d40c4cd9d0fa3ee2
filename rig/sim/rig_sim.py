"""The built-in simulated rig: every device's simulator on its own pty or TCP port.

x, y and z are three Zaber devices daisy-chained on one port, θ a PR-mode Modbus
drive, the gauge an FT300 (or an M8128). ``config_toml()`` is a rig config pointing
at those ports, loaded through the same validator as a user's file, so the drivers
open the simulators exactly as they would open hardware.
"""

from __future__ import annotations

from rig.clock import Clock, SystemClock
from rig.config import RigConfig, parse_config
from rig.sim.camera_sim import SimCameraSource
from rig.sim.ft300_sim import Ft300Sim
from rig.sim.link import SimServer
from rig.sim.m8128_sim import M8128Sim
from rig.sim.modbus_rtu import RtuServer
from rig.sim.pr_drive_sim import PrDriveSim
from rig.sim.world import SimWorld, WorldSpec
from rig.sim.zaber_sim import ZaberChainSim, ZaberDeviceSim
from sensor_sim.world_contact import rig_contact

ZABER_MICROSTEP_MM = 0.047625e-3  # a common Zaber linear-stage microstep
THETA_PULSES_PER_REV = 10000
THETA_DEG_PER_REV = 4.0  # a 90:1 worm rotary stage
ZABER_DEVICES = {"x": 1, "y": 2, "z": 3}
THETA_DEVICE_ID = 1
# Reply timeout written into the simulated rig's config. In-process (--sim) it counts
# simulated time (rig/transport/peer.py), so machine load cannot trip it; a client of
# `rig sim serve` in another process waits this long in real time, as on hardware.
DEVICE_TIMEOUT_S = 0.3


class SimulatedRig:
    def __init__(self, clock: Clock | None = None, *, transport: str = "pty", gauge: str = "ft300",
                 spec: WorldSpec | None = None, seed: int = 0, indenter: str = "sphere10mm",
                 sensor_kind: str = "rgb", contact=None, gauge_rate_hz: float = 100.0):
        if gauge not in ("ft300", "m8128", "ati_netft"):
            raise ValueError(f"simulated gauge must be 'ft300', 'm8128' or 'ati_netft', got {gauge!r}")
        self.clock = clock or SystemClock()
        if contact is None:
            contact = rig_contact(indenter)
        self.world = SimWorld(self.clock, spec, contact=contact, seed=seed)
        self.sensor_kind = sensor_kind
        self.triggered_camera = False  # acquisition sets it: frames only on capture
        # A discrete-event (manual) clock has the devices emit synchronously on each
        # advance: a sample stamped now is from now. Otherwise the gauge's latency bound
        # in clock seconds: a contact solve (up to ~60 ms of real time) stretched by the
        # clock's speed-up, plus a tick.
        self.discrete_time = hasattr(self.clock, "add_listener")
        factor = getattr(self.clock, "factor", 1.0)
        self.gauge_latency_s = 0.0 if self.discrete_time else round(max(0.05, 0.08 * factor), 3)
        self.gauge_kind = gauge
        stages = self.world.stages
        self.zaber = ZaberChainSim(self.clock, {
            number: ZaberDeviceSim(stages[axis], ZABER_MICROSTEP_MM) for axis, number in ZABER_DEVICES.items()
        })
        self.theta = PrDriveSim(stages["theta"], pulses_per_rev=THETA_PULSES_PER_REV, travel_per_rev=THETA_DEG_PER_REV)
        self.servers: dict[str, SimServer] = {}
        try:
            self.servers["stages"] = SimServer(self.zaber, self.clock, transport=transport, name="zaber")
            self.servers["theta"] = SimServer(RtuServer({THETA_DEVICE_ID: self.theta}), self.clock,
                                              transport=transport, name="pr-drive")
            self.netft = None
            if gauge == "ati_netft":  # UDP + HTTP on loopback, not a byte-stream server
                from rig.sim.ati_netft_sim import AtiNetFtSim

                self.netft = AtiNetFtSim(self.world, rate_hz=max(gauge_rate_hz, 1000.0))
            else:
                model = (Ft300Sim(self.world, rate_hz=gauge_rate_hz) if gauge == "ft300"
                         else M8128Sim(self.world, rate_hz=gauge_rate_hz))
                model.schedule.report_on_advance = self.discrete_time
                self.servers["gauge"] = SimServer(model, self.clock, transport=transport, name=gauge)
        except Exception:
            self.close()
            raise

    def config_toml(self, *, with_camera: bool = True) -> str:
        geo = self.world.spec.geometry
        stage_specs = self.world.spec.stages
        lines = ['[rig]', 'name = "simulated rig"', '']
        for axis, number in ZABER_DEVICES.items():
            g, s = geo[axis], stage_specs[axis]
            scale = ZABER_MICROSTEP_MM * g.sign
            ends = sorted(g.sign * (p - g.origin) for p in s.travel)
            lines += [
                f'[axes.{axis}]', 'driver = "zaber"', f'port = "{self.servers["stages"].url}"',
                f'device = {number}', f'scale = {scale!r}', f'offset = {-g.sign * g.origin * 1.0!r}',
                f'travel = [{ends[0]!r}, {ends[1]!r}]', f'max_speed = {s.max_speed!r}', 'jog_speed = 1.0',
                f'timeout_s = {DEVICE_TIMEOUT_S!r}', '',
            ]
        g, s = geo["theta"], stage_specs["theta"]
        lines += [
            '[axes.theta]', 'driver = "pr_drive"', 'unit = "deg"', f'port = "{self.servers["theta"].url}"',
            f'device = {THETA_DEVICE_ID}', f'pulses_per_rev = {THETA_PULSES_PER_REV}',
            f'travel_per_rev = {THETA_DEG_PER_REV!r}', f'offset = {-g.origin!r}',
            f'travel = [{s.travel[0] - g.origin!r}, {s.travel[1] - g.origin!r}]',
            f'max_speed = {s.max_speed!r}', 'jog_speed = 5.0', f'timeout_s = {DEVICE_TIMEOUT_S!r}', '',
        ]
        if self.gauge_kind == "ft300":
            lines += ['[gauge]', 'driver = "ft300"', f'port = "{self.servers["gauge"].url}"', 'device_id = 9',
                      'mode = "stream"', f'fresh_after_s = {self.gauge_latency_s!r}', '']
        elif self.gauge_kind == "ati_netft":
            lines += ['[gauge]', 'driver = "ati_netft"', 'port = "127.0.0.1"', f'rdt_port = {self.netft.rdt_port}',
                      f'http_port = {self.netft.http_port}', 'mode = "stream"',
                      f'fresh_after_s = {self.gauge_latency_s!r}', '']
        else:
            lines += ['[gauge]', 'driver = "m8128"', f'port = "{self.servers["gauge"].url}"', 'mode = "stream"',
                      f'fresh_after_s = {self.gauge_latency_s!r}', '']
        if with_camera:
            lines += ['[camera]', 'driver = "sim"', 'width = 256', 'height = 256', 'fps = 25.0',
                      'discard_frames = 2', '']
        lines += ['[safety]', 'max_force_N = [10.0, 10.0, 40.0]', 'max_torque_Nmm = [300.0, 300.0, 200.0]', '']
        return "\n".join(lines)

    def config(self, *, with_camera: bool = True) -> RigConfig:
        return parse_config(self.config_toml(with_camera=with_camera), "<built-in simulated rig>")

    def camera_source(self, *, fps: float = 25.0, height: int = 256, width: int = 256,
                      triggered: bool = False) -> SimCameraSource:
        return SimCameraSource(self.world, self.clock, fps=fps, height=height, width=width, kind=self.sensor_kind,
                               triggered=triggered or self.triggered_camera)

    def close(self) -> None:
        for server in self.servers.values():
            server.close()
        if getattr(self, "netft", None) is not None:
            self.netft.close()

    def __enter__(self) -> "SimulatedRig":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
