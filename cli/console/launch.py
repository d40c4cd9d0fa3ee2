"""What ``rig console`` and ``dataset view`` do: set the console up, print its address, serve."""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path

from cli.console.runs import RunLibrary
from cli.console.server import ConsoleOptions, bind, make_token, serve, url_of
from cli.console.worker import RigWorker, open_console_rig
from common.errors import ConfigError
from common.sensors import SENSOR_KINDS


def console_options(
    *,
    config: Path | None,
    sim: bool,
    live: bool,
    runs: list[Path],
    files: list[Path] = (),  # type: ignore[assignment]  # a tuple default is safe (never mutated)
    token: str | None = None,
    sensor: str = "rgb",
) -> ConsoleOptions:
    """The console's content: the rig when ``live`` (opened by the worker thread once the
    server starts), the run files of ``runs`` folders and ``files``; ``sensor``: the live
    camera's kind (the simulated camera renders it; marker kinds get marker-flow arrows)."""
    worker = None
    if live:
        noop = lambda *_: None
        worker = RigWorker(
            functools.partial(open_console_rig, config, sim, sensor),
            on_state=noop,
            on_event=noop,
            on_frame=noop,
            sensor=sensor,
            runs_folder=Path(runs[0]) if runs else Path("runs"),
            simulated=sim,
        )
    files = [Path(f) for f in files]
    return ConsoleOptions(
        worker,
        RunLibrary(folders=list(runs), files=files),
        token=token,
        open_run=files[0].name if files else None,
        sensor=sensor,
    )


def run_console(
    *,
    config: Path | None,
    sim: bool,
    live: bool,
    host: str,
    port: int,
    runs: list[Path],
    files: list[Path] = (),  # type: ignore[assignment]
    say: Callable[[str], None] = print,
    sensor: str = "rgb",
) -> None:
    """Serve until Ctrl-C; ``say`` gets the address (with the token when not on loopback)."""
    if sensor not in SENSOR_KINDS:
        raise ConfigError(
            "rig console", "--sensor", f"{sensor!r} is not a sensor kind: one of {', '.join(SENSOR_KINDS)}"
        )
    if live and not sim:  # no config, or a broken one: refused here, not shown as a dead page
        from cli.session import resolve_config_path
        from rig.config import load_config

        load_config(resolve_config_path(config))
    token = make_token(host)
    sock = bind(host, port)
    options = console_options(config=config, sim=sim, live=live, runs=runs, files=files, token=token, sensor=sensor)
    say(banner(url_of(sock, host, token), live))
    if token:
        say(f"listening on {host}: the page needs the token above; share it only with people at the rig")
    serve(options, sock)


def banner(url: str, live: bool) -> str:
    """The first line: the address, and what Ctrl-C does (with no rig there is nothing to stop)."""
    return f"console at {url}   (Ctrl-C stops{'; moves stop and the rig closes' if live else ''})"
