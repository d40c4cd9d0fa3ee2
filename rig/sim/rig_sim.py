"""The built-in simulated rig: every device's simulator on its own pty or TCP port.

x, y and z are three Zaber devices daisy-chained on one port, θ a PR-mode Modbus
drive, the gauge any registered kind with a simulator (rig/config/registry.py; an
FT300 by default). ``config_toml()`` is a rig config pointing at those ports, loaded
through the same validator as a user's file, so the drivers open the simulators
exactly as they would open hardware.
"""

from __future__ import annotations

import math

from common.errors import ConfigError
from objects.object_file import is_object_file, load_object_file
from rig.clock import Clock, SystemClock
from rig.config import RigConfig, parse_config
from rig.config.registry import kind, load
from rig.sim.camera_sim import CameraStreamServer, SimCameraSource
from rig.sim.link import SimServer
from rig.sim.modbus_rtu import RtuServer
from rig.sim.pr_drive_sim import PrDriveSim
from rig.sim.served import ServedDevice
from rig.sim.stage import Stopping
from rig.sim.world import SimWorld, WorldSpec
from rig.sim.zaber_sim import ZaberChainSim, ZaberDeviceSim
from sensor_sim.world_contact import rig_cells, rig_contact

ZABER_MICROSTEP_MM = 0.047625e-3  # a common Zaber linear-stage microstep
THETA_PULSES_PER_REV = 10000
THETA_DEG_PER_REV = 4.0  # a 90:1 worm rotary stage
ZABER_DEVICES = {"x": 1, "y": 2, "z": 3}
THETA_DEVICE_ID = 1
# Reply timeout written into the simulated rig's config. In-process (--sim) it counts
# simulated time (rig/transport/peer.py), so machine load cannot trip it; a client of
# `rig sim serve` in another process waits this long in real time, as on hardware.
DEVICE_TIMEOUT_S = 0.3
# What `rig sim serve` writes instead: its clients wait in real time, writes included, and on a
# loaded 2-core machine a 0.3 s write timeout was seen to trip mid-run against a served rig.
SERVED_DEVICE_TIMEOUT_S = 1.0
CAMERA_SIZE_PX = 256  # the simulated camera's frame without a profile: a square pad (a profile sets its own)


class SimulatedRig:
    def __init__(
        self,
        clock: Clock | None = None,
        *,
        transport: str = "pty",
        gauge: str = "ft300",
        spec: WorldSpec | None = None,
        seed: int = 0,
        indenter: str = "sphere10mm",
        sensor_kind: str = "rgb",
        contact=None,
        gauge_rate_hz: float = 100.0,
        profile=None,
        gauge_at_every_step: bool = True,
    ):
        """``profile``: a ``sensor_sim.profile.SensorProfile`` for the gel (thickness, modulus,
        field of view) and the camera (optics, background, noise, frame size: its own, square or
        not); None: the shipped default. ``gauge_at_every_step=False``: on a discrete-event clock
        the gauge reports only at its rate, not also at every step of the clock (the overshoot
        tests: a 10 Hz gauge's samples are 100 ms apart, as on hardware)."""
        gauge_row = kind("gauge", gauge, path="<built-in simulated rig>", key="gauge")
        if gauge_row.simulator is None:
            raise ValueError(f"gauge kind {gauge!r} has no simulator in its registry row")
        self.clock = clock or SystemClock()
        self.profile = profile
        # the camera's frame (width, height): the profile's own, or the default square
        self.camera_px = (CAMERA_SIZE_PX, CAMERA_SIZE_PX) if profile is None else (profile.width_px, profile.height_px)
        if contact is None:
            # an object file without a height map: NoHeightMap, one line, before anything opens
            shape = load_object_file(indenter).indenter() if is_object_file(indenter) else indenter
            contact = (
                rig_contact(shape)
                if profile is None
                else rig_contact(
                    shape, profile.gel(), profile.geometry(cells=rig_cells(profile.width_mm, profile.height_mm))
                )
            )
        self.world = SimWorld(self.clock, spec, contact=contact, seed=seed)
        if is_object_file(indenter):
            relief = load_object_file(indenter).height_map
            if relief is not None and relief.relief_mm >= self.gel_thickness_mm:
                raise ConfigError(
                    indenter,
                    "file",
                    f"the height map's relief is {relief.relief_mm:.3g} mm, not less than the simulated gel's "
                    f"{self.gel_thickness_mm:g} mm: its tallest part would press through the gel",
                )
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
        self.zaber = ZaberChainSim(
            self.clock,
            {number: ZaberDeviceSim(stages[axis], ZABER_MICROSTEP_MM) for axis, number in ZABER_DEVICES.items()},
        )
        self.theta = PrDriveSim(stages["theta"], pulses_per_rev=THETA_PULSES_PER_REV, travel_per_rev=THETA_DEG_PER_REV)
        self.servers: dict[str, SimServer] = {}
        self.gauge_sim: ServedDevice | None = None
        self.camera_server: CameraStreamServer | None = None  # serve_camera(): frames for other processes
        try:
            self.servers["stages"] = SimServer(self.zaber, self.clock, transport=transport, name="zaber")
            self.servers["theta"] = SimServer(
                RtuServer({THETA_DEVICE_ID: self.theta}), self.clock, transport=transport, name="pr-drive"
            )
            self.gauge_sim = load(gauge_row.simulator)(
                self.world, self.clock, transport=transport, rate_hz=gauge_rate_hz
            )
            self.servers.update(self.gauge_sim.servers)
            schedule = getattr(self.gauge_sim.model, "schedule", None)
            if schedule is not None and not gauge_at_every_step:
                schedule.report_on_advance = False
        except Exception:
            self.close()
            raise

    def config_toml(self, *, with_camera: bool = True, device_timeout_s: float = DEVICE_TIMEOUT_S) -> str:
        geo = self.world.spec.geometry
        stage_specs = self.world.spec.stages
        lines = ["[rig]", 'name = "simulated rig"', ""]
        for axis, number in ZABER_DEVICES.items():
            g, s = geo[axis], stage_specs[axis]
            scale = ZABER_MICROSTEP_MM * g.sign
            ends = sorted(g.sign * (p - g.origin) for p in s.travel)
            lines += [
                f"[axes.{axis}]",
                'driver = "zaber"',
                f'port = "{self.servers["stages"].url}"',
                f"device = {number}",
                f"scale = {scale!r}",
                f"offset = {-g.sign * g.origin * 1.0!r}",
                f"travel = [{ends[0]!r}, {ends[1]!r}]",
                f"max_speed = {s.max_speed!r}",
                "jog_speed = 1.0",
                f"timeout_s = {device_timeout_s!r}",
                *self._stop_keys(axis, abrupt=False),
                "",
            ]
        g, s = geo["theta"], stage_specs["theta"]
        lines += [
            "[axes.theta]",
            'driver = "pr_drive"',
            'unit = "deg"',
            f'port = "{self.servers["theta"].url}"',
            f"device = {THETA_DEVICE_ID}",
            f"pulses_per_rev = {THETA_PULSES_PER_REV}",
            f"travel_per_rev = {THETA_DEG_PER_REV!r}",
            f"offset = {-g.origin!r}",
            f"travel = [{s.travel[0] - g.origin!r}, {s.travel[1] - g.origin!r}]",
            f"max_speed = {s.max_speed!r}",
            "jog_speed = 5.0",
            f"timeout_s = {device_timeout_s!r}",
            *self._stop_keys("theta", abrupt=True),  # the PR drive's stop is its emergency stop
            "",
        ]
        lines += ["[gauge]", f'driver = "{self.gauge_kind}"']
        assert self.gauge_sim is not None  # set in __init__ (close() is the only place it may be missing)
        lines += [f"{key} = {toml_value(value)}" for key, value in self.gauge_sim.keys.items()]
        lines += ['mode = "stream"', f"fresh_after_s = {self.gauge_latency_s!r}", ""]
        if with_camera:
            served = self.camera_server
            lines += (
                ["[camera]", 'driver = "stream"', f'device = "{served.url}"']
                if served
                else ["[camera]", 'driver = "sim"']
            )
            width, height = self.camera_px
            lines += [f"width = {width}", f"height = {height}", "fps = 25.0", "discard_frames = 2"]
            if self.profile is not None and getattr(self.profile, "path", None):
                # the frames' sensor, recorded in every run made through this config (a served rig's too)
                lines.append(f"sensor_profile = {toml_value(str(self.profile.path))}")
            solver = getattr(self.world.contact, "solver", None)
            if solver is not None:  # the rendered pad's calibration, stored in every run file
                lines.append(f"mm_per_px = {solver.geometry.width_mm / width!r}")
            lines.append("")
        lines += ["[safety]", "max_force_N = [10.0, 10.0, 40.0]", "max_torque_Nmm = [300.0, 300.0, 200.0]"]
        lines += [f"gel_thickness_mm = {self.gel_thickness_mm!r}", ""]
        return "\n".join(lines)

    def _stop_keys(self, axis: str, *, abrupt: bool) -> list[str]:
        """The config's stop_latency_s and stop_decel: what the simulated device does, as a
        user copies them from a stage's manual (docs/hardware.md)."""
        stopping = self.world.stages[axis].stopping
        decel = stopping.abrupt_decel if abrupt else stopping.decel
        return [f"stop_latency_s = {stopping.reaction_s!r}", f"stop_decel = {round(decel, 3)!r}"]

    @property
    def gel_thickness_mm(self) -> float:
        """The simulated gel's thickness (its profile's, or the contact model's own), as a rig
        config states it for the depth guard; 3 mm for a contact model without a gel."""
        if self.profile is not None:
            return float(self.profile.gel_thickness_mm)
        solver = getattr(self.world.contact, "solver", None)
        thickness = getattr(getattr(solver, "gel", None), "thickness_mm", None)
        return float(thickness) if thickness is not None and math.isfinite(thickness) else 3.0

    def config(self, *, with_camera: bool = True) -> RigConfig:
        return parse_config(self.config_toml(with_camera=with_camera), "<built-in simulated rig>")

    def camera_source(
        self, *, fps: float = 25.0, height: int | None = None, width: int | None = None, triggered: bool = False
    ) -> SimCameraSource:
        """The simulated camera; ``width`` × ``height`` default to the rig's frame (``camera_px``)."""
        width = self.camera_px[0] if width is None else width
        height = self.camera_px[1] if height is None else height
        return SimCameraSource(
            self.world,
            self.clock,
            fps=fps,
            height=height,
            width=width,
            kind=self.sensor_kind,
            triggered=triggered or self.triggered_camera,
            profile=self.profile,
        )

    @property
    def netft(self):
        """The simulated ATI Net F/T when that is the gauge (its UDP and HTTP ports), else None."""
        return self.gauge_sim.model if self.gauge_kind == "ati_netft" and self.gauge_sim is not None else None

    def stopping(self) -> dict[str, Stopping]:
        """Per axis, how its simulated device stops: the stop deceleration, the reaction time
        before it and the emergency deceleration (mm or deg, as the axis), as the device's
        settings are now (docs/simulator.md, "Stopping")."""
        return {axis: stage.stopping for axis, stage in self.world.stages.items()}

    def serve_camera(self) -> CameraStreamServer:
        """Serve the camera on a loopback TCP port; ``config_toml()`` then names it (driver
        "stream"), so another process (`rig sim serve`'s clients) reads frames like a device."""
        if self.camera_server is None:
            source = self.camera_source(triggered=True)
            self.camera_server = CameraStreamServer(source)
        return self.camera_server

    def close(self) -> None:
        camera_server = getattr(self, "camera_server", None)
        if camera_server is not None:
            camera_server.close()
        gauge_sim = getattr(self, "gauge_sim", None)
        for server in self.servers.values():
            if gauge_sim is None or server not in gauge_sim.servers.values():
                server.close()
        if gauge_sim is not None:
            gauge_sim.close()

    def __enter__(self) -> "SimulatedRig":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def toml_value(value) -> str:
    """A TOML literal for a config value a simulator hands over (str, bool, int, float)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return repr(value)
