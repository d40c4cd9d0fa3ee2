"""What the ``rig`` commands share: --config, --sim, --object and --profile, and how a failure ends a command.

``friendly_errors`` turns every failure into one red line and a non-zero exit; ``say`` and ``note``
put progress and the guards' notes on stderr, so stdout keeps only the result.
"""

from __future__ import annotations

import functools
import logging
from pathlib import Path
from typing import Annotated, Optional

import typer

ConfigOpt = Annotated[
    Optional[Path],
    typer.Option("--config", "-c", help="Rig config TOML (default: $RIG_CONFIG, then ./rig.toml).", dir_okay=False),
]
SimOpt = Annotated[bool, typer.Option("--sim", help="Use the built-in simulated rig instead of hardware.")]


def known_object(name: str | None) -> str | None:
    """--object: a library object's name or an object file that exists; BadParameter otherwise."""
    if name is None:
        return None
    from objects.indenters import INDENTERS
    from objects.object_file import is_object_file

    if name in INDENTERS or (is_object_file(name) and Path(name).is_file()):
        return name
    raise typer.BadParameter(
        f"{name!r} is neither a library object ({', '.join(INDENTERS)}) nor an object file (.toml) that exists"
    )


ObjectOpt = Annotated[
    Optional[str],
    typer.Option(
        "--object",
        callback=known_object,
        help="The indenter now mounted (a library object or object file name): the rig remembers a gel surface per "
        "indenter, so a different one descends at the in-contact speed until it sees the gel (default: the one "
        "named last).",
    ),
]
ProfileOpt = Annotated[
    Optional[Path],
    typer.Option(
        help="With --sim: the simulated sensor's profile TOML (`rig sensor calibrate` writes one; default: the "
        "shipped GelSight Mini).",
        dir_okay=False,
    ),
]


def fail(message: str, code: int = 1):
    """End the command: ``error: MESSAGE`` in red on stderr, exit ``code``."""
    typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
    raise typer.Exit(code)


def friendly_errors(fn):
    """Every failure becomes one red line and a non-zero exit, never a traceback: rig
    errors and bad input exit 1; a signal exits 128 + its number (Ctrl-C 130, SIGTERM
    143, SIGHUP 129) after the motion session stopped everything."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from common.errors import ToolError
        from rig.interruption import MotionInterrupted

        try:
            return fn(*args, **kwargs)
        except (typer.Exit, typer.Abort, typer.TyperException):
            raise  # typer's own ways out (a command's exit code, a bad option)
        except ToolError as exc:
            fail(str(exc))
        except (FileNotFoundError, ValueError) as exc:
            fail(str(exc))
        except MotionInterrupted as exc:
            typer.secho(
                f"interrupted ({exc.signal_name}): motion stopped, devices closed", fg=typer.colors.YELLOW, err=True
            )
            raise typer.Exit(exc.exit_code) from None
        except KeyboardInterrupt:
            typer.secho("interrupted: motion stopped, devices closed", fg=typer.colors.YELLOW, err=True)
            raise typer.Exit(130) from None
        except Exception as exc:  # a driver's or the OS's error: still one line, naming its type
            logging.getLogger("rig").debug("unexpected error", exc_info=True)
            fail(f"{type(exc).__name__}: {exc}")

    return wrapper


def say(text: str) -> None:
    """Progress on stderr (stdout keeps only the result): a long move shows it started."""
    typer.echo(f"{text} (Ctrl-C stops)", err=True)


def note(text: str) -> None:
    """What the speed envelope or the depth guard changed about a move, on stderr."""
    typer.secho(f"note: {text}", fg=typer.colors.YELLOW, err=True)
