"""Ports whose far end is a simulator running in this process.

A simulated device answers in zero simulated time, but its thread may be starved of
CPU for a while on a loaded machine. A real-time reply timeout then aborted simulated
runs. A simulator registers its port URL here; a transport that
opens that URL asks the simulator, instead of a wall clock, whether a reply is still
coming: a reply is late only when the simulator has taken the request and has nothing
due within the timeout of *simulated* time. A simulator that does not take a request
within ``stall_limit_s`` real seconds is treated as dead (a DeviceTimeout).

Hardware ports are never registered, so their timeouts stay the real ones.
"""

from __future__ import annotations

import threading
from enum import Enum
from typing import Protocol


class Outlook(Enum):
    READING = "reading"  # the simulator has not taken all the host's bytes yet
    COMING = "coming"  # a reply is on the wire, or due within the timeout
    SILENT = "silent"  # nothing will arrive within the timeout of simulated time


class InProcessPeer(Protocol):
    stall_limit_s: float  # real seconds the simulator may take to answer before it is dead

    @property
    def alive(self) -> bool:
        """False once the simulator stopped."""

    def counters(self) -> tuple[int, int]:
        """(bytes taken from the host and processed, bytes sent to the host) so far."""

    def reply_outlook(self, base: tuple[int, int], written: int, read: int, timeout_s: float) -> Outlook:
        """Whether a reply to the host's bytes is coming. ``base`` is ``counters()`` when
        the host opened the port; ``written``/``read`` count the host's bytes since. On a
        discrete-event clock this advances simulated time: to a reply due within the
        timeout, or by the whole timeout when none is (a timeout takes simulated time)."""


_PEERS: dict[str, InProcessPeer] = {}
_LOCK = threading.Lock()


def register(url: str, peer: InProcessPeer) -> None:
    with _LOCK:
        _PEERS[url] = peer


def unregister(url: str, peer: InProcessPeer) -> None:
    with _LOCK:
        if _PEERS.get(url) is peer:
            del _PEERS[url]


def lookup(url: str) -> InProcessPeer | None:
    with _LOCK:
        return _PEERS.get(url)
