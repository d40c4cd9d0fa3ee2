"""Terminal rendering of rig state."""

from __future__ import annotations

import numpy as np
from rich.console import Console
from rich.table import Table

from cli.options import fixed
from cli.run_display import output_console
from rig.config.registry import kind
from rig.types import WRENCH_COMPONENTS, WRENCH_UNITS


def device_line(role: str, cfg, where: str) -> str:
    """'gauge  ft300: Robotiq FT300 (Modbus RTU) on /dev/ttyUSB2', the kind's title from the registry."""
    return f"{role:6s} {cfg.driver}: {kind(role, cfg.driver).title} on {where}"


def print_status(rig, console: Console | None = None) -> None:
    console = console or output_console()
    st = rig.status()
    table = Table(title=f"{rig.config.name}")
    for col in ("axis", "position", "unit", "state", "homed", "travel", "warnings"):
        table.add_column(col)
    for name, s in st.axes.items():
        cfg = rig.config.axes[name]
        table.add_row(
            name,
            fixed(s.position, 4),
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
        console.print("wrench as the gauge reads it (not tared): " + wrench_line(values))
        tare = rig.state.tare
        if tare is not None and not np.any(getattr(rig.gauge, "bias", 1.0)):
            console.print(
                "wrench minus the tare remembered by rig zero: " + wrench_line(values - np.asarray(tare.raw_N))
            )
    if rig.gauge is not None and rig.guard is not None and rig.axes:
        print_safety(rig, console)


def wrench_line(values) -> str:
    """'Fx +0.120 N  Fy -0.080 N  …  Mz +1.500 N·mm'."""
    return "  ".join(f"{c} {fixed(v, 3)} {u}" for c, v, u in zip(WRENCH_COMPONENTS, values, WRENCH_UNITS))


def print_safety(rig, console: Console) -> None:
    """What the guard knows: the measured gauge period and stop latencies, the speed envelope
    in contact, the remembered gel surface and depth floor, and the remembered tare."""
    from rig.rig_state import age_text

    envelope = rig.envelope()
    timing = envelope.timing
    poll_s = rig.config.safety.poll_s
    console.print(
        f"guard: gauge sample period {1000 * timing.gauge_period_s:.1f} ms (measured) + latency bound "
        f"{1000 * timing.gauge_latency_s:.0f} ms, checked every {1000 * poll_s:.0f} ms; stop latency "
        + ", ".join(
            f"{name} {1000 * timing.stop_latency_s(name):.1f} ms (round trip {1000 * timing.exchange_s[name]:.1f} "
            f"measured + device {1000 * timing.device_reaction_s[name]:.0f} ms)"
            for name in rig.axes
        )
    )
    caps = []
    for name in rig.axes:
        cap = envelope.cap(name, "gel" if name == "z" else "pressed", poll_s)
        caps.append(f"{name} {cap.speed:.3g} {cap.unit}/s")
    safety = rig.config.safety
    console.print(
        "speed envelope in contact: " + ", ".join(caps) + f" (stiffness {safety.stiffness_N_per_mm:g} N/mm, "
        f"shear {safety.shear_stiffness_N_per_mm:g} N/mm, twist {safety.twist_stiffness_Nmm_per_deg:g} N·mm/deg; "
        f"overshoot at most {safety.overshoot_margin:.0%} of a limit)"
    )
    guard = rig.depth_guard()
    state = rig.state
    indenter = state.mounted or "the unnamed indenter (no --object given yet)"
    if guard is None:
        why = state.why_unknown(state.surfaces.get(state.mounted))
        console.print(
            f"gel surface of {indenter}: not known ({why}; rig find-contact, or the first contact a move sees); "
            "until then every z descent runs at the in-contact speed"
        )
    else:
        console.print(
            f"gel surface of {indenter}: z = {guard.surface_z:.4f} mm ({guard.how}); depth floor "
            f"z = {guard.floor_z:.4f} mm; full speed only above z = "
            f"{guard.surface_z + rig.config.safety.surface_uncertainty_mm + 0.5:.4f} mm"
        )
    others = sorted(name or "unnamed" for name in state.surfaces if name != state.mounted)
    if others:
        console.print(f"surfaces also remembered for: {', '.join(others)} (used when that indenter is named)")
    tare = rig.state.tare
    if tare is None:
        console.print("tare: none remembered (rig zero)")
    else:
        console.print(f"tare: unloaded Fz {fixed(tare.fz_N, 4)} N raw, taken {age_text(tare.t_unix)} (rig zero)")


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
