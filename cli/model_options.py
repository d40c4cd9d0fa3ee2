"""What the model commands share: the --threads and --mixed-precision options, the sampler settings' parser
and their one-line errors."""

from __future__ import annotations

import functools
from typing import Annotated, Optional

import typer

Threads = Annotated[
    Optional[int],
    typer.Option(
        help="torch CPU threads (default: one per core not busy with other processes, model/denoiser/threads.py; "
        "or the TACTILE_TORCH_THREADS environment variable).",
        min=1,
        max=256,
    ),
]

SamplingPrecision = Annotated[
    str,
    typer.Option(
        "--mixed-precision",
        help="The network's arithmetic when sampling: auto (CPU: bf16 where the CPU has it natively, else fp32; "
        "GPU: fp32), no (fp32) or bf16 (model/denoiser/precision.py).",
    ),
]


def one_line_errors(fn):
    """Expected failures (bad files, values, checkpoints, splits) become one red line and exit 1; a
    Ctrl-C, the entry point's one line and SIGINT (Typer would end it with status 130, silently)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from cli.entry import INTERRUPTED, die_by_sigint

        try:
            return _said_in_one_line(fn, *args, **kwargs)
        except KeyboardInterrupt:
            from model.training.train_job import end_failed_process

            end_failed_process(130, say=INTERRUPTED)  # one of several training processes
            die_by_sigint()

    return wrapper


def _said_in_one_line(fn, *args, **kwargs):
    from cli.entry import ctrl_c_after
    from cli.one_line import passes_through, unexpected

    with ctrl_c_after():  # torch's import (below) is where a Ctrl-C aborted the process
        import torch  # noqa: F401
    from common.errors import ToolError
    from model.denoiser.checkpoint import CheckpointError
    from model.training.train_job import end_failed_process

    try:
        return fn(*args, **kwargs)
    except (ToolError, CheckpointError, ValueError, KeyError, OSError) as exc:
        message = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
    except Exception as exc:  # nothing expected it: still one line, naming its type (cli/one_line.py)
        if passes_through(exc):
            raise
        message = unexpected(exc, "model")
    typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
    end_failed_process(1)  # one of several training processes: ends at once
    raise typer.Exit(1)


def sampler_settings(text: str) -> list[tuple[str, int]]:
    """--settings: sampler:steps pairs, comma-separated (BadParameter naming the option otherwise)."""
    try:
        return [(s.split(":")[0], int(s.split(":")[1])) for s in text.split(",")]
    except (IndexError, ValueError):
        raise typer.BadParameter(f"--settings: expected sampler:steps[,sampler:steps...], got {text!r}") from None
