"""What ``rig console`` and ``dataset view`` do: set the console up, print its address, serve."""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path

from cli.console.runs import RunLibrary
from cli.console.server import ConsoleOptions, bind, make_token, serve, url_of
from cli.console.worker import RigWorker, open_console_rig


def console_options(
    *,
    config: Path | None,
    sim: bool,
    live: bool,
    runs: list[Path],
    files: list[Path] = (),  # type: ignore[assignment]  # a tuple default is safe (never mutated)
    token: str | None = None,
) -> ConsoleOptions:
    """The console's content: the rig when ``live`` (opened by the worker thread once the
    server starts), the run files of ``runs`` folders and ``files``."""
    worker = None
    if live:
        noop = lambda *_: None
        worker = RigWorker(
            functools.partial(open_console_rig, config, sim), on_state=noop, on_event=noop, on_frame=noop
        )
    files = [Path(f) for f in files]
    return ConsoleOptions(
        worker,
        RunLibrary(folders=list(runs), files=files),
        token=token,
        open_run=files[0].name if files else None,
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
) -> None:
    """Serve until Ctrl-C; ``say`` gets the address (with the token when not on loopback)."""
    token = make_token(host)
    sock = bind(host, port)
    options = console_options(config=config, sim=sim, live=live, runs=runs, files=files, token=token)
    say(f"console at {url_of(sock, host, token)}   (Ctrl-C stops; moves stop and the rig closes)")
    if token:
        say(f"listening on {host}: the page needs the token above; share it only with people at the rig")
    serve(options, sock)
