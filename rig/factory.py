"""Open the devices a rig config names, through their registry rows (rig/config/registry.py).

No list of kinds here: each section's ``driver`` picks a row, whose opener is loaded and
called with an ``OpenContext`` (clock, shared ports, the in-process simulated rig).
"""

from __future__ import annotations

from typing import Any, Callable

from rig.clock import Clock
from rig.config import AxisConfig, CameraConfig, GaugeConfig
from rig.config.registry import OpenContext, kind, load
from rig.drivers.camera import Camera


class PortPool:
    """One open transport per port URL, shared by the devices daisy-chained on it
    (a Zaber chain, a Modbus bus). The config refuses two drivers on one port."""

    def __init__(self):
        self._open: dict[str, Any] = {}

    def shared(self, url: str, open_: Callable[[], Any]) -> Any:
        """The transport open on ``url``, opened by ``open_()`` the first time."""
        if url not in self._open:
            self._open[url] = open_()
        return self._open[url]

    def close(self) -> None:
        for transport in self._open.values():
            transport.close()
        self._open.clear()


def _opener(role: str, cfg) -> Callable:
    return load(kind(role, cfg.driver).opener)


def open_axis(cfg: AxisConfig, pool: PortPool, clock: Clock | None = None):
    return _opener("axis", cfg)(cfg, OpenContext(clock, pool))


def open_gauge(cfg: GaugeConfig, clock: Clock, pool: PortPool):
    """The gauge, streaming when ``mode = "stream"``; closed again if the stream cannot start."""
    gauge = _opener("gauge", cfg)(cfg, OpenContext(clock, pool))
    if cfg.mode == "stream":
        try:
            gauge.start_stream()
        except BaseException:
            gauge.close()
            raise
    return gauge


def open_camera(cfg: CameraConfig, clock: Clock, sim=None) -> Camera:
    source = _opener("camera", cfg)(cfg, OpenContext(clock, None, sim))
    return Camera(
        source, clock, name=f"camera ({cfg.driver} {cfg.device})".replace(" )", ")"), discard_frames=cfg.discard_frames
    )
