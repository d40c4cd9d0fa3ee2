"""``rig sim serve``: the built-in simulated rig served on ptys or loopback sockets, with a config pointing at it."""

from __future__ import annotations

import enum
from pathlib import Path
from typing import Annotated

import typer

from cli.options import number
from cli.rig_options import ProfileOpt, friendly_errors, known_object
from rig.config.registry import kinds

app = typer.Typer(help="The built-in simulated rig (devices on ptys or loopback sockets).", no_args_is_help=True)


class Transport(str, enum.Enum):
    pty = "pty"
    tcp = "tcp"


# The gauges the simulated rig can stand in: the registry rows with a simulator.
GaugeKind = enum.Enum(  # type: ignore[misc]  # members come from the registry, so mypy cannot list them
    "GaugeKind", [(name, name) for name in kinds("gauge", simulated=True)], type=str
)


@app.command("serve")
@friendly_errors
def sim_serve(
    out: Annotated[Path, typer.Option(help="Where to write the rig config that points at the simulators.")] = Path(
        "rig-sim.toml"
    ),
    transport: Annotated[
        Transport, typer.Option(help="pty (virtual serial ports) or tcp (socket:// on 127.0.0.1).")
    ] = Transport.pty,
    gauge: Annotated[GaugeKind, typer.Option(help="Which force gauge to simulate.")] = GaugeKind("ft300"),
    gauge_rate_hz: Annotated[
        float,
        typer.Option(help="The simulated gauge's sample rate, Hz.", callback=number(positive=True, high=2000.0)),
    ] = 100.0,
    indenter: Annotated[
        str, typer.Option("--object", help="The indenter the simulated rig carries.", callback=known_object)
    ] = "sphere10mm",
    profile: ProfileOpt = None,
):
    """Start the simulated rig, print its port URLs, write a config; runs until Ctrl-C.
    Refused while another `rig sim serve` writes the same --out."""
    import faulthandler
    import os
    import signal
    import threading

    faulthandler.register(signal.SIGUSR1)  # `kill -USR1 PID` prints every thread's stack (a stuck simulator)

    from cli.session import load_sim_profile
    from rig.interruption import SignalsAsExceptions
    from rig.ownership import claim
    from rig.sim.rig_sim import SERVED_DEVICE_TIMEOUT_S, SimulatedRig

    sensor_profile = load_sim_profile(profile)
    with (
        claim({os.path.realpath(out): ["rig sim serve --out"]}, subject="config"),
        SimulatedRig(
            transport=transport.value,
            gauge=gauge.value,
            profile=sensor_profile,
            gauge_rate_hz=gauge_rate_hz,
            indenter=indenter,
        ) as simulated,
    ):
        camera = simulated.serve_camera()
        written = "# Written by `rig sim serve`; valid while that process runs (removed when it stops).\n" + (
            simulated.config_toml(device_timeout_s=SERVED_DEVICE_TIMEOUT_S)
        )
        try:
            with SignalsAsExceptions():  # SIGTERM and SIGHUP too: the config is removed either way
                out.write_text(written)
                for name, server in simulated.servers.items():
                    typer.echo(f"{name:7s} {server.url}")
                typer.echo(f"{'camera':7s} {camera.url}")
                typer.echo(f"{'sensor':7s} {sensor_profile.name} ({sensor_profile.path})")
                typer.echo(f"{'object':7s} {indenter}; gauge at {gauge_rate_hz:g} Hz")
                typer.echo(f"config  {out}   (try: rig status --config {out})")
                typer.echo("serving; Ctrl-C stops")
                threading.Event().wait()
        except KeyboardInterrupt as exc:
            typer.echo(f"stopped ({getattr(exc, 'signal_name', 'SIGINT')})")
        finally:
            _remove_if_ours(out, written)


def _remove_if_ours(path: Path, written: str) -> None:
    """Remove the config `rig sim serve` wrote, unless someone changed it since (then it is theirs)."""
    try:
        if path.read_text() == written:
            path.unlink()
            typer.echo(f"removed {path}")
        else:
            typer.echo(f"left {path} in place: it was changed after `rig sim serve` wrote it")
    except OSError:
        pass  # already gone, or unreadable: nothing of ours to remove
