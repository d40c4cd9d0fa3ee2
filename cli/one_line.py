"""The last resort of the dataset, model and sensor commands: an error nothing expected is one line.

Each app turns the errors it expects (bad files, values, splits) into its own one-line message;
``unexpected`` words any other exception as one line naming its type, as ``rig``'s commands do
(cli/rig_options.py, ``friendly_errors``); the traceback goes to the debug log only. typer's own ways
out (an exit code, a bad option) are not errors and pass through (``passes_through``).
"""

from __future__ import annotations

import logging

import typer


def passes_through(exc: BaseException) -> bool:
    """typer's own ways out (typer.Exit, Abort, BadParameter, ...): not errors to word here."""
    return isinstance(exc, (typer.Exit, typer.Abort, typer.TyperException))


def unexpected(exc: BaseException, logger: str) -> str:
    """One line for an exception no command expected: its type and its first line."""
    logging.getLogger(logger).debug("unexpected error", exc_info=exc)
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else "(no message)"
    return f"{type(exc).__name__}: {text}"
