"""Open the devices a rig config names: shared ports, drivers, gauge, camera."""

from __future__ import annotations

from rig.clock import Clock
from rig.config import AxisConfig, CameraConfig, GaugeConfig
from rig.drivers.camera import Camera, FolderSource, open_v4l2
from rig.drivers.ft300 import FT300
from rig.drivers.m8128 import M8128
from rig.drivers.pr_drive import PrDriveAxis
from rig.drivers.wrench_stream import GaugeBase
from rig.drivers.zaber import ZaberAxis, ZaberChain
from rig.transport.modbus_bus import ModbusBus
from rig.transport.serial_link import SerialLink


class PortPool:
    """One open transport per port URL, shared by the axes daisy-chained on it."""

    def __init__(self):
        self._zaber: dict[str, ZaberChain] = {}
        self._modbus: dict[str, ModbusBus] = {}

    def zaber(self, cfg: AxisConfig) -> ZaberChain:
        if cfg.port not in self._zaber:
            link = SerialLink(cfg.port, baudrate=cfg.baudrate, timeout_s=cfg.timeout_s, device=f"Zaber chain on {cfg.port}")
            self._zaber[cfg.port] = ZaberChain(link, retries=cfg.retries)
        return self._zaber[cfg.port]

    def modbus(self, url: str, baudrate: int, timeout_s: float, retries: int, label: str) -> ModbusBus:
        if url not in self._modbus:
            self._modbus[url] = ModbusBus(url, baudrate=baudrate, timeout_s=timeout_s, retries=retries, device=label)
        return self._modbus[url]

    def close(self) -> None:
        for chain in self._zaber.values():
            chain.close()
        for bus in self._modbus.values():
            bus.close()
        self._zaber.clear()
        self._modbus.clear()


def open_axis(cfg: AxisConfig, pool: PortPool):
    if cfg.driver == "zaber":
        return ZaberAxis(pool.zaber(cfg), name=cfg.name, device=cfg.device, axis=cfg.axis_number,
                         scale=cfg.scale, offset=cfg.offset, unit=cfg.unit)
    bus = pool.modbus(cfg.port, cfg.baudrate, cfg.timeout_s, cfg.retries, f"Modbus bus on {cfg.port}")
    axis = PrDriveAxis(bus, name=cfg.name, device_id=cfg.device, pulses_per_rev=cfg.pulses_per_rev,
                       travel_per_rev=cfg.travel_per_rev, offset=cfg.offset, unit=cfg.unit,
                       requires_home=cfg.requires_home)
    axis.check_pulses_per_rev()
    return axis


def open_gauge(cfg: GaugeConfig, clock: Clock, pool: PortPool) -> GaugeBase:
    if cfg.driver == "ft300":
        bus = pool.modbus(cfg.port, cfg.baudrate, cfg.timeout_s, cfg.retries, f"FT300 on {cfg.port}")
        gauge: GaugeBase = FT300(bus, clock, device_id=cfg.device_id, fresh_after_s=cfg.fresh_after_s)
    elif cfg.driver == "ati_netft":
        from rig.drivers.ati_netft import AtiNetFT

        gauge = AtiNetFT(cfg.port, clock, rdt_port=cfg.rdt_port, http_port=cfg.http_port, timeout_s=cfg.timeout_s,
                         retries=cfg.retries, mode=cfg.rdt_mode, fresh_after_s=cfg.fresh_after_s)
    else:
        link = SerialLink(cfg.port, baudrate=cfg.baudrate, timeout_s=cfg.timeout_s, device=f"M8128 on {cfg.port}")
        gauge = M8128(link, clock, rate_hz=cfg.rate_hz, fresh_after_s=cfg.fresh_after_s)
        try:
            gauge.configure()
        except Exception:
            link.close()
            raise
    if cfg.mode == "stream":
        gauge.start_stream()
    return gauge


def open_camera(cfg: CameraConfig, clock: Clock, sim=None) -> Camera:
    if cfg.driver == "sim":
        if sim is None:
            from rig.errors import NotBuiltYet

            raise NotBuiltYet("camera driver 'sim' works only with the in-process simulated rig (--sim); "
                              "`rig sim serve` does not export a camera yet")
        source = sim.camera_source(fps=cfg.fps, height=cfg.height, width=cfg.width)
    elif cfg.driver == "folder":
        source = FolderSource(cfg.device, clock, fps=cfg.fps)
    elif cfg.driver == "video":
        import cv2

        source = cv2.VideoCapture(cfg.device)
        if not source.isOpened():
            raise FileNotFoundError(f"camera: cannot open video file {cfg.device}")
    else:
        source = open_v4l2(cfg.device, width=cfg.width, height=cfg.height, fps=cfg.fps,
                           exposure=cfg.exposure, white_balance_K=cfg.white_balance_K)
    return Camera(source, clock, name=f"camera ({cfg.driver} {cfg.device})".replace(" )", ")"),
                  discard_frames=cfg.discard_frames)
