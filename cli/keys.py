"""Single keypresses for interactive jogging: raw mode on a terminal, plain characters otherwise."""

from __future__ import annotations

import sys
from typing import Iterator, TextIO

ARROWS = {"A": "up", "B": "down", "C": "right", "D": "left"}


def keys(stream: TextIO | None = None) -> Iterator[str]:
    """Yield keys: characters, or 'up'/'down'/'left'/'right'/'esc'. Ends at end of input."""
    stream = stream or sys.stdin
    if stream.isatty():
        yield from _tty_keys(stream)
        return
    while True:
        ch = stream.read(1)
        if not ch:
            return
        if not ch.isspace():
            yield ch


def _tty_keys(stream: TextIO) -> Iterator[str]:
    import termios
    import tty

    fd = stream.fileno()
    saved = termios.tcgetattr(fd)
    try:
        tty.setcbreak(fd)
        while True:
            ch = stream.read(1)
            if not ch:
                return
            if ch == "\x1b":
                nxt = stream.read(1)
                if nxt == "[":
                    yield ARROWS.get(stream.read(1), "esc")
                    continue
                yield "esc"
                continue
            if ch == "\x03":
                raise KeyboardInterrupt
            yield ch
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)
