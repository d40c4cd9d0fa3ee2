"""Small pieces of wording that several commands print alike."""

from __future__ import annotations


def reason_only(status: str, reason: str | None) -> str:
    """A run's reason without its status word again: "interrupted (SIGINT); resume with --resume" of an
    interrupted run → "SIGINT; resume with --resume" ("" for none)."""
    reason = (reason or "").strip()
    if reason.lower().startswith(status.lower()):
        rest = reason[len(status) :].strip()
        if rest.startswith("(") and ")" in rest:  # "interrupted (SIGINT); resume …" → "SIGINT; resume …"
            inner, _, after = rest[1:].partition(")")
            rest = inner + after
        return rest.lstrip(":;, ").strip()
    return reason


def status_text(status: str, reason: str | None) -> str:
    """A run's status with its reason: "interrupted (SIGINT; resume with --resume)", never the status twice
    ("interrupted (interrupted (SIGINT)…") when the reason already begins with it."""
    rest = reason_only(status, reason)
    return f"{status} ({rest})" if rest else status


def signed(value: float, digits: int, sign: str = "+") -> str:
    """``value`` to ``digits`` decimals (``sign`` "+" shows it, "" not), never "-0.00" nor e-notation: a value
    that rounds to zero reads as zero."""
    text = f"{float(value):{sign}.{digits}f}"
    return f"{0.0:{sign}.{digits}f}" if float(text) == 0 else text
