"""A device that plays back an exact script of (expected request, reply) byte pairs.

For byte-exact driver tests: ``check`` fails on any unexpected byte and on any
expected exchange left unconsumed, as PyMeasure's protocol harness does.
"""

from __future__ import annotations

from rig.sim.link import RequestReplyDevice


class ScriptedDevice(RequestReplyDevice):
    def __init__(self, exchanges: list[tuple[bytes, bytes]]):
        self.exchanges = list(exchanges)
        self._buf = b""
        self.errors: list[str] = []

    def feed(self, data: bytes, now_s: float) -> list[bytes]:
        self._buf += data
        out: list[bytes] = []
        while self.exchanges and len(self._buf) >= len(self.exchanges[0][0]):
            expected, reply = self.exchanges.pop(0)
            got, self._buf = self._buf[: len(expected)], self._buf[len(expected) :]
            if got != expected:
                self.errors.append(f"expected {expected.hex(' ')}, got {got.hex(' ')}")
                return out
            if reply:
                out.append(reply)
        if not self.exchanges and self._buf:
            self.errors.append(f"unexpected bytes {self._buf.hex(' ')}")
            self._buf = b""
        return out

    def check(self) -> None:
        problems = list(self.errors)
        if self.exchanges:
            problems.append(f"{len(self.exchanges)} exchange(s) never happened, next: {self.exchanges[0][0].hex(' ')}")
        if problems:
            raise AssertionError("; ".join(problems))
