"""Interactive jogging from the keyboard or the HID pendant."""

from __future__ import annotations

import typer

from cli.keys import keys
from cli.options import fixed
from rig.errors import SafetyError

HELP = "keys: + / up = step up, - / down = step down, ] = step x10, [ = step /10, q = quit"


def jog_with_keys(m, axis: str, step: float, speed: float | None, stream=None) -> None:
    """Jog inside the motion session ``m`` (rig.motion) until q, Esc or the end of input."""
    rig = m.rig
    unit = rig.config.axes[axis].unit
    typer.echo(HELP)
    typer.echo(f"{axis} = {fixed(rig.axes[axis].position(), 4, sign=False)} {unit}, step {step:g} {unit}")
    for key in keys(stream):
        if key in ("q", "esc"):
            break
        if key in ("]", "["):
            step = step * 10 if key == "]" else step / 10
            typer.echo(f"step {step:g} {unit}")
            continue
        direction = {"+": 1, "=": 1, "up": 1, "-": -1, "_": -1, "down": -1}.get(key)
        if direction is None:
            typer.echo(HELP)
            continue
        try:
            pos = m.jog(axis, step=direction * step, speed=speed)
        except SafetyError as exc:  # a refused step is reported and jogging goes on
            typer.secho(str(exc), fg=typer.colors.YELLOW)
            continue
        typer.echo(f"{axis} = {fixed(pos, 4, sign=False)} {unit}")


def jog_with_pendant(m, axis: str, step: float, speed: float | None, pendant=None) -> None:
    """Inside the motion session ``m``, each poll with the cap deflected steps the axis by
    ``step`` × deflection; button 1 quits."""
    from rig.drivers.spacemouse import deflection, open_spacemouse

    rig = m.rig
    cfg = rig.config.pendant
    pendant = pendant or open_spacemouse(cfg.vendor_id if cfg else None, cfg.product_id if cfg else None)
    deadband = cfg.deadband if cfg else 0.15
    unit = rig.config.axes[axis].unit
    typer.echo(f"jogging {axis} with {pendant.name}; press button 1 to quit")
    try:
        while True:
            state = pendant.poll(timeout_ms=50)
            if state.buttons & 1:
                break
            d = deflection(state, axis, deadband)
            if d:
                try:
                    pos = m.jog(axis, step=d * step, speed=speed)
                except SafetyError as exc:
                    typer.secho(str(exc), fg=typer.colors.YELLOW)
                    continue
                typer.echo(f"{axis} = {fixed(pos, 4, sign=False)} {unit}")
    finally:
        pendant.close()
