"""``rig protocols list|show`` and ``rig run-protocol``: their options; the work is in cli/protocol_cmds.py.

``run_protocol_cmd`` is a command of the ``rig`` app itself (cli/rig_app.py registers it there).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from cli.rig_options import ConfigOpt, ProfileOpt, SimOpt, friendly_errors

app = typer.Typer(
    help="The protocol library: list protocols, show one's steps, duration and frames.", no_args_is_help=True
)


@app.command("list")
@friendly_errors
def protocols_list():
    """List the library's protocols with their duration and frame count."""
    from cli.protocol_cmds import list_protocols

    list_protocols()


SetOpt = Annotated[
    Optional[list[str]],
    typer.Option(
        "--set",
        help="Change one protocol key for this run, as section.key=value (repeatable), e.g. "
        "--set motion.speed_mm_s=0.1 (the paper's ~700 frames per object) or --set protocol.sensor=rgb_markers. "
        "The run file stores the changed protocol. Default: the protocol as written.",
    ),
]


@app.command("show")
@friendly_errors
def protocols_show(
    name: Annotated[str, typer.Argument(help="A library protocol name, or a path to a .toml file.")],
    settings: SetOpt = None,
):
    """Print a protocol's steps, its true duration, frame count and disk estimate."""
    from cli.protocol_cmds import show_protocol

    show_protocol(name, settings=settings or [])


def _origin(value: str) -> tuple[float, float, float, float]:
    try:
        parts = tuple(float(v) for v in value.split(","))
    except ValueError:
        raise typer.BadParameter(f"expected four numbers x,y,z,theta, got {value!r}") from None
    if len(parts) != 4 or not all(math.isfinite(p) for p in parts):
        raise typer.BadParameter(f"'--origin' expects four finite numbers x,y,z,theta, got {value!r}")
    return parts


@friendly_errors
def run_protocol_cmd(
    name: Annotated[str, typer.Argument(help="A library protocol (rig protocols list), or a path to a .toml file.")],
    out: Annotated[
        Optional[Path],
        typer.Option(help="The HDF5 run file to write; must not exist (default: runs/NAME-YYYYmmdd-HHMMSS.h5)."),
    ] = None,
    resume: Annotated[
        Optional[Path], typer.Option(help="Continue this interrupted run file where it stopped (default: a new run).")
    ] = None,
    dry_run: Annotated[
        bool,
        typer.Option(
            "--dry-run",
            help="Check every move against the config's limits and print duration and frame count; move nothing.",
        ),
    ] = False,
    origin: Annotated[
        Optional[str],
        typer.Option(
            help="The contact point in axis coordinates: x,y,z (mm),theta (deg). Default: the origin rig "
            "find-contact --set-origin remembered for this rig, else 0,0,0,0 (the simulated rig's contact point); "
            "the run says which it used."
        ),
    ] = None,
    settings: SetOpt = None,
    config: ConfigOpt = None,
    sim: SimOpt = False,
    profile: ProfileOpt = None,
):
    """Run a protocol with synchronised capture (frame + wrench + pose at the protocol's rate) into HDF5.

    With --sim the simulated rig runs on simulated time, as fast as the frames can be made.
    """
    from cli.protocol_cmds import run_protocol

    run_protocol(
        name,
        out=out,
        resume=resume,
        dry_run=dry_run,
        config=config,
        sim=sim,
        origin=_origin(origin) if origin is not None else None,
        settings=settings or [],
        profile=profile,
    )
