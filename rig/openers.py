"""Openers of the built-in device kinds, named by their rows in ``rig/config/registry.py``.

Each is ``open_x(cfg, ctx) -> device``: it turns one validated config section into an
open driver (axes, gauges) or capture source (cameras). ``ctx.ports.shared(url, open)``
gives the devices daisy-chained on one port one transport. A new kind's opener can live
beside its driver instead; the registry row names where.
"""

from __future__ import annotations

from rig.config import AxisConfig, CameraConfig, GaugeConfig
from rig.config.registry import OpenContext
from rig.drivers.camera import FolderSource, open_v4l2
from rig.drivers.camera_stream import StreamSource
from rig.drivers.ft300 import FT300
from rig.drivers.m8128 import M8128
from rig.drivers.pr_drive import PrDriveAxis
from rig.drivers.zaber import ZaberAxis, ZaberChain
from rig.errors import NotBuiltYet, RigError
from rig.transport.modbus_bus import ModbusBus
from rig.transport.serial_link import SerialLink


def _baudrate(cfg: AxisConfig | GaugeConfig) -> int:
    """The serial baud rate: every serial kind's registry row has one, so its config does too."""
    if cfg.baudrate is None:
        raise RigError(f"{cfg.driver} on {cfg.port}: a serial device needs a baudrate")
    return cfg.baudrate


def _modbus(cfg: AxisConfig | GaugeConfig, ctx: OpenContext, label: str) -> ModbusBus:
    baudrate = _baudrate(cfg)
    return ctx.ports.shared(
        cfg.port,
        lambda: ModbusBus(cfg.port, baudrate=baudrate, timeout_s=cfg.timeout_s, retries=cfg.retries, device=label),
    )


def open_zaber(cfg: AxisConfig, ctx: OpenContext) -> ZaberAxis:
    chain = ctx.ports.shared(
        cfg.port,
        lambda: ZaberChain(
            SerialLink(cfg.port, baudrate=cfg.baudrate, timeout_s=cfg.timeout_s, device=f"Zaber chain on {cfg.port}"),
            retries=cfg.retries,
        ),
    )
    return ZaberAxis(
        chain, name=cfg.name, device=cfg.device, axis=cfg.axis_number, scale=cfg.scale, offset=cfg.offset, unit=cfg.unit
    )


def open_pr_drive(cfg: AxisConfig, ctx: OpenContext) -> PrDriveAxis:
    bus = _modbus(cfg, ctx, f"Modbus bus on {cfg.port}")
    axis = PrDriveAxis(
        bus,
        name=cfg.name,
        device_id=cfg.device,
        pulses_per_rev=cfg.pulses_per_rev,
        travel_per_rev=cfg.travel_per_rev,
        offset=cfg.offset,
        unit=cfg.unit,
        requires_home=cfg.requires_home,
    )
    axis.check_pulses_per_rev()
    return axis


def open_ft300(cfg: GaugeConfig, ctx: OpenContext) -> FT300:
    bus = _modbus(cfg, ctx, f"FT300 on {cfg.port}")
    return FT300(bus, ctx.clock, device_id=cfg.device_id, fresh_after_s=cfg.fresh_after_s)


def open_m8128(cfg: GaugeConfig, ctx: OpenContext) -> M8128:
    link = SerialLink(cfg.port, baudrate=_baudrate(cfg), timeout_s=cfg.timeout_s, device=f"M8128 on {cfg.port}")
    gauge = M8128(link, ctx.clock, rate_hz=cfg.rate_hz, fresh_after_s=cfg.fresh_after_s)
    try:
        gauge.configure()
    except Exception:
        link.close()
        raise
    return gauge


def open_ati_netft(cfg: GaugeConfig, ctx: OpenContext):
    from rig.drivers.ati_netft import AtiNetFT

    return AtiNetFT(
        cfg.port,
        ctx.clock,
        rdt_port=cfg.rdt_port,
        http_port=cfg.http_port,
        timeout_s=cfg.timeout_s,
        retries=cfg.retries,
        mode=cfg.rdt_mode,
        fresh_after_s=cfg.fresh_after_s,
    )


def open_v4l2_camera(cfg: CameraConfig, ctx: OpenContext):
    return open_v4l2(
        cfg.device,
        width=cfg.width,
        height=cfg.height,
        fps=cfg.fps,
        exposure=cfg.exposure,
        white_balance_K=cfg.white_balance_K,
    )


def open_folder_camera(cfg: CameraConfig, ctx: OpenContext) -> FolderSource:
    return FolderSource(cfg.device, ctx.clock, fps=cfg.fps)


def open_video_camera(cfg: CameraConfig, ctx: OpenContext):
    import cv2

    source = cv2.VideoCapture(cfg.device)
    if not source.isOpened():
        raise FileNotFoundError(f"camera: cannot open video file {cfg.device}")
    return source


def open_sim_camera(cfg: CameraConfig, ctx: OpenContext):
    if ctx.sim is None:
        raise NotBuiltYet(
            "camera driver 'sim' works only with the in-process simulated rig (--sim); "
            "`rig sim serve` writes a 'stream' camera for other processes"
        )
    return ctx.sim.camera_source(fps=cfg.fps, height=cfg.height, width=cfg.width)


def open_stream_camera(cfg: CameraConfig, ctx: OpenContext) -> StreamSource:
    return StreamSource(cfg.device, ctx.clock, fps=cfg.fps, timeout_s=cfg.timeout_s, size=(cfg.height, cfg.width))
