"""Zaber ASCII protocol: framing, checksum and reply parsing.

Command ``/<device> <axis> <id> <command>[:<checksum>]\\n``; reply
``@<dd> <a> <id> <OK|RJ> <IDLE|BUSY> <flag> <data>[:<checksum>]\\r\\n``.
Message ids are 0-99; we send them as two digits, as zaber-motion does, and accept
one or two digits back, as Zaber's other clients do (manual, "Message IDs").
The checksum is the two's complement of the byte sum (mod 256) of everything
between the leading ``/``/``@`` and the ``:``, as two upper-case hex digits.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

# Warning flags, highest priority first (Zaber ASCII manual, "Warning Flags").
FAULT_FLAGS = {
    "FD": "driver disabled",
    "FQ": "encoder error",
    "FS": "stalled and stopped",
    "FT": "excessive twist",
    "FB": "stream bounds error",
    "FP": "interpolated path deviation",
    "FE": "limit error",
}
WARNING_FLAGS = {
    "WH": "device not homed",
    "WL": "unexpected limit trigger",
    "WP": "invalid calibration type",
    "WV": "voltage out of range",
    "WT": "controller temperature high",
    "WM": "displaced when stationary",
    "WR": "no reference position",
}
NOTICE_FLAGS = {"NC", "NI", "ND", "NU", "NJ"}
REJECTION_REASONS = {
    "AGAIN",
    "BADAXIS",
    "BADCOMMAND",
    "BADDATA",
    "BADMESSAGEID",
    "DEVICEONLY",
    "FULL",
    "LOCKSTEP",
    "NOACCESS",
    "PARKED",
    "STATUSBUSY",
}
NOT_REFERENCED = {"WH", "WR"}

# Native velocity unit: 1 microstep/s = 1.6384 data units (Zaber ASCII "maxspeed").
VELOCITY_UNITS_PER_USTEP_S = 1.6384

_REPLY = re.compile(
    r"^@(?P<device>\d{2}) (?P<axis>\d+) (?:(?P<id>\d{1,2}) )?(?P<flag>OK|RJ) (?P<status>IDLE|BUSY) "
    r"(?P<warning>\S\S) (?P<data>[^:\r\n]*?)(?::(?P<checksum>[0-9A-F]{2}))?\r?\n$"
)


def checksum(body: str) -> str:
    return f"{(-sum(body.encode('ascii'))) & 0xFF:02X}"


def format_command(
    device: int, axis: int, command: str, message_id: int | None = None, with_checksum: bool = False
) -> bytes:
    body = f"{device} {axis}"
    if message_id is not None:
        body += f" {message_id:02d}"
    if command:
        body += f" {command}"
    if with_checksum:
        body += ":" + checksum(body)
    return f"/{body}\n".encode("ascii")


@dataclass(frozen=True)
class Reply:
    device: int
    axis: int
    message_id: int | None
    flag: str  # OK | RJ
    status: str  # IDLE | BUSY
    warning: str  # "--" or the highest-priority flag
    data: str
    raw: bytes

    @property
    def busy(self) -> bool:
        return self.status == "BUSY"


class ReplyParseError(ValueError):
    pass


def parse_reply(line: bytes) -> Reply:
    """Parse one reply line; raises ReplyParseError on bad framing or checksum."""
    try:
        text = line.decode("ascii")
    except UnicodeDecodeError as exc:
        raise ReplyParseError(f"non-ASCII bytes in reply {line!r}") from exc
    m = _REPLY.match(text)
    if m is None:
        raise ReplyParseError(f"malformed reply {line!r}")
    if m["checksum"] is not None:
        body = text[1 : text.index(":")]
        if checksum(body) != m["checksum"]:
            raise ReplyParseError(f"checksum mismatch in reply {line!r}")
    return Reply(
        device=int(m["device"]),
        axis=int(m["axis"]),
        message_id=int(m["id"]) if m["id"] is not None else None,
        flag=m["flag"],
        status=m["status"],
        warning=m["warning"],
        data=m["data"].strip(),
        raw=line,
    )
