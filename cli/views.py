"""Terminal rendering of rig state."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table

from rig.config.registry import kind
from rig.types import WRENCH_COMPONENTS, WRENCH_UNITS


def device_line(role: str, cfg, where: str) -> str:
    """'gauge  ft300: Robotiq FT300 (Modbus RTU) on /dev/ttyUSB2', the kind's title from the registry."""
    return f"{role:6s} {cfg.driver}: {kind(role, cfg.driver).title} on {where}"


def print_status(rig, console: Console | None = None) -> None:
    console = console or Console()
    st = rig.status()
    table = Table(title=f"{rig.config.name}")
    for col in ("axis", "position", "unit", "state", "homed", "travel", "warnings"):
        table.add_column(col)
    for name, s in st.axes.items():
        cfg = rig.config.axes[name]
        table.add_row(
            name,
            f"{s.position:+.4f}",
            cfg.unit,
            s.state.value,
            "yes" if s.homed else "NO",
            f"[{cfg.travel[0]:g}, {cfg.travel[1]:g}]",
            " ".join(s.warnings) or "-",
        )
    console.print(table)
    by_port: dict[str, list] = {}
    for name in st.axes:
        by_port.setdefault(rig.config.axes[name].port, []).append(rig.config.axes[name])
    for port, cfgs in by_port.items():
        console.print(device_line("axis", cfgs[0], port) + f" ({', '.join(c.name for c in cfgs)})")
    if rig.gauge is not None:
        gauge = rig.config.gauge
        how = ", streaming" if gauge.mode == "stream" else ", polled"
        console.print(device_line("gauge", gauge, gauge.port) + how)
    if rig.camera is not None:
        print_camera(rig.config.camera, rig.camera.report(), console)
    if st.wrench is not None:
        values = st.wrench.as_array()
        console.print(
            "wrench (untared raw minus session tare): "
            + "  ".join(f"{c} {v:+.3f} {u}" for c, v, u in zip(WRENCH_COMPONENTS, values, WRENCH_UNITS))
        )


def _lock(locked: bool | None, what: str, key: str) -> str:
    if locked is None:
        return f"{what} n/a"
    return f"{what} locked" if locked else f"[yellow]{what} AUTO (drifts during a run: set {key} in [camera])[/]"


def print_camera(cfg, report, console: Console) -> None:
    """One line: 'camera stream: … on tcp://…: 256x256 at 25 fps, exposure locked, white balance
    locked, newest frame 12 ms old'; what is off (auto exposure, another size) in yellow."""
    fps = f"{report.fps:g} fps" if report.fps else "fps not reported"
    size = f"{report.width_px}x{report.height_px}"
    if (report.width_px, report.height_px) != (cfg.width, cfg.height):
        size = f"[yellow]{size} (config asks {cfg.width}x{cfg.height})[/]"
    console.print(
        device_line("camera", cfg, cfg.device or "this process")
        + f": {size} at {fps}, "
        + _lock(report.exposure_locked, "exposure", "exposure")
        + ", "
        + _lock(report.white_balance_locked, "white balance", "white_balance_K")
        + f", newest frame {1000 * report.newest_age_s:.0f} ms old"
    )
