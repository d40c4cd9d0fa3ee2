"""Numeric command-line options checked where they enter: finite, within bounds, the option named.

typer's ``min=`` lets ``inf`` through (and options without it take ``nan``); a NaN speed or
step would reach the stages. Use ``callback=number(...)`` on every float option.
"""

from __future__ import annotations

from typing import Any

import typer

from common.table import number_problem


def number(*, low: float | None = None, high: float | None = None, positive: bool = False):
    """A typer callback refusing NaN, inf and values outside the bounds, naming the option
    ("Invalid value for '--speed': must be > 0 and <= 1000.0, got nan"); None passes (not given)."""

    def check(ctx: typer.Context, param: typer.CallbackParam, value: Any):
        if value is None:
            return value
        problem = number_problem(value, low=low, high=high, positive=positive)
        if problem:
            # typer annotates `param` with its private parameter class, but hands callbacks a
            # CallbackParam (the click.Parameter it is): typer's own mismatch, fine at run time.
            raise typer.BadParameter(problem, ctx=ctx, param=param)  # type: ignore[arg-type]
        return value

    return check


def fixed(value: float, digits: int, *, sign: bool = True) -> str:
    """``value`` to ``digits`` decimals for printing, never "-0.0000": what rounds to zero prints as zero."""
    rounded = round(float(value), digits) + 0.0  # + 0.0 turns -0.0 into 0.0
    return f"{rounded:+.{digits}f}" if sign else f"{rounded:.{digits}f}"
