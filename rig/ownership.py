"""One owner per device: claims on the endpoints a process is about to open.

A claim is an advisory ``flock(LOCK_EX | LOCK_NB)`` on one lock file per endpoint in the
runtime folder (``runtime_dir``). The process that takes the lock then writes who it is into
the file (pid, command line, host, when), so a second process is refused in one line naming
the holder (``DeviceBusy``). The kernel drops a flock when its process dies, so a killed
holder leaves a record whose lock is free: the next claim takes it over and says so in one
line (``Claim.notes``, also logged at WARNING). Releasing empties the file and unlocks it;
lock files are never deleted: deleting a flock'd file races (a process that opened it just
before the unlink locks the orphaned inode while a newcomer locks a new file, and both "hold"
the device).

Endpoints, what two processes must not share (``rig_endpoints``):

- a serial port: the real path of its device node (``/dev/serial/by-id/…`` and ``/dev/ttyUSB0``
  are one port; a pty's slave counts); ``socket://HOST:PORT`` and ``rfc2217://HOST:PORT``:
  ``HOST:PORT``. Axes daisy-chained on one port share its claim.
- a network gauge (ATI Net F/T): ``HOST:RDT_PORT/udp``.
- a camera served over TCP (``tcp://HOST:PORT``): ``HOST:PORT``; a V4L2 camera: the real path
  of ``/dev/videoN``; recorded frames and the in-process simulated camera: none.

Claims cover the processes of one user on one machine (the runtime folder is the user's);
the serial ports are also locked on their device node (rig/transport/exclusive.py), which
keeps out other users' processes of this tool too.
"""
# Over 400 lines (462): one advisory-lock protocol: endpoint names, holder records, taking and releasing a
# flock and the Claim holding them must agree on one lock-file format, so they change together.

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import ipaddress
import json
import logging
import math
import os
import re
import shlex
import socket
import stat
import sys
import threading
import time
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import asdict, dataclass
from pathlib import Path

from rig.config import CameraConfig, GaugeConfig, RigConfig
from rig.drivers.camera_stream import SCHEME as STREAM_SCHEME
from rig.drivers.camera_stream import parse_address
from rig.errors import DeviceBusy, RigError

log = logging.getLogger("rig.ownership")

RECORD_BYTES = 4096  # the holder's record, padded to one page: written by one pwrite, read whole
COMMAND_CHARS = 400  # a longer command line is cut (a `python -c` script)
RECORD_WAIT_S = 0.5  # how long a refused claim waits for the holder's record (written right after its lock)


# -- where -----------------------------------------------------------------------------------
def runtime_dir() -> Path:
    """``/tmp/tactile-rig-UID``, made (0700) if missing: one folder per user whatever the process's
    environment (a cron job, `sudo -u`, a systemd service and a terminal must all meet in it);
    ``$TACTILE_RUNTIME_DIR`` replaces it (the tests' own folder). Either must be a real folder (not
    a link) owned by this user that no one else may write into or read (mode 0700 or stricter):
    another user who could replace a lock file there could make this tool write through a link
    or take a device's lock from under it. RigError naming the folder and the fix otherwise."""
    chosen = os.environ.get("TACTILE_RUNTIME_DIR")
    folder = Path(chosen) if chosen else Path(f"/tmp/tactile-rig-{os.getuid()}")
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        st = os.lstat(folder)
    except OSError as exc:
        raise RigError(
            f"runtime folder {folder}: cannot make it ({exc.strerror}); set TACTILE_RUNTIME_DIR to a writable folder"
        ) from None
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid():
        raise RigError(
            f"runtime folder {folder}: not a folder owned by uid {os.getuid()} (a link, or another user's); "
            "remove it or set TACTILE_RUNTIME_DIR to a folder of yours with mode 0700"
        )
    if st.st_mode & 0o077:
        raise RigError(
            f"runtime folder {folder}: mode {stat.S_IMODE(st.st_mode):04o} lets other users in; "
            f"`chmod 700 {folder}` (device locks must be yours alone)"
        )
    return folder


def lock_path(endpoint: str, folder: Path | None = None) -> Path:
    """The lock file of ``endpoint``: its name made safe, and a hash that keeps two apart."""
    safe = re.sub(r"[^A-Za-z0-9.-]+", "_", endpoint).strip("_")[:80]
    digest = hashlib.sha1(endpoint.encode()).hexdigest()[:8]
    return (folder or runtime_dir()) / f"{safe}-{digest}.lock"


# -- what ------------------------------------------------------------------------------------
def host_port(host: str, port: int | str, transport: str = "tcp") -> str:
    """``HOST:PORT`` (``HOST:PORT/udp``), the host's address written one way."""
    host = host.strip("[]").lower()
    host = "127.0.0.1" if host == "localhost" else host
    try:
        host = str(ipaddress.ip_address(host))
    except ValueError:  # a name: its address, so that a name and its address are one device
        with contextlib.suppress(OSError, UnicodeError):
            host = socket.gethostbyname(host)
    shown = f"[{host}]" if ":" in host else host
    return f"{shown}:{port}" + ("" if transport == "tcp" else f"/{transport}")


def serial_endpoint(url: str) -> str | None:
    """The endpoint of a serial port URL; None for ``loop://`` (nothing to share)."""
    scheme, sep, rest = url.partition("://")
    if not sep:
        return os.path.realpath(url)
    if scheme in ("socket", "rfc2217"):
        host, _, port = rest.split("?")[0].split("/")[0].rpartition(":")
        return host_port(host, port)
    return None if scheme == "loop" else url


def gauge_endpoint(cfg: GaugeConfig) -> str | None:
    """A serial gauge's port; a network gauge's host and the UDP port its records come from."""
    if cfg.baudrate is not None:  # a serial kind (its registry row has a baud rate)
        return serial_endpoint(cfg.port)
    return host_port(cfg.port, cfg.options.get("rdt_port", "*"), "udp")


def camera_endpoint(cfg: CameraConfig) -> str | None:
    """A served camera's ``HOST:PORT``, a V4L2 device's real path; None for recorded frames and
    the in-process simulated camera."""
    device = str(cfg.device)
    if device.startswith(STREAM_SCHEME):
        return host_port(*parse_address(device))
    device = f"/dev/video{device}" if device.isdigit() else device
    return os.path.realpath(device) if device.startswith("/dev/") else None


def rig_endpoints(config: RigConfig, axes: Iterable[str], *, gauge: bool, camera: bool) -> dict[str, list[str]]:
    """Endpoint → the roles using it, for the devices asked for."""
    uses: dict[str, list[str]] = {}

    def use(endpoint: str | None, role: str) -> None:
        if endpoint is not None:
            uses.setdefault(endpoint, []).append(role)

    for name in axes:
        use(serial_endpoint(config.axes[name].port), f"axis {name}")
    if gauge and config.gauge is not None:
        use(gauge_endpoint(config.gauge), "gauge")
    if camera and config.camera is not None:
        use(camera_endpoint(config.camera), "camera")
    return uses


def roles_text(roles: Iterable[str]) -> str:
    """["axis x", "axis y", "gauge"] → "axes x, y, gauge"."""
    roles = list(roles)
    axes = [r.removeprefix("axis ") for r in roles if r.startswith("axis ")]
    rest = [r for r in roles if not r.startswith("axis ")]
    return ", ".join(([f"ax{'es' if len(axes) > 1 else 'is'} {', '.join(axes)}"] if axes else []) + rest)


# -- who -------------------------------------------------------------------------------------
def typed_command(argv: list[str]) -> str:
    """A process's command line as typed: ``/venv/bin/python /venv/bin/rig console …`` (a
    console script) → ``rig console …``; ``/usr/bin/python3 -m pytest`` → ``python3 -m pytest``."""
    words = list(argv) or ["?"]
    first = os.path.basename(words[0])
    if first.startswith("python") and len(words) > 1 and not words[1].startswith("-") and not words[1].endswith(".py"):
        words = [os.path.basename(words[1]), *words[2:]]
    else:
        words = [first, *words[1:]]
    if "-c" in words[1:2]:  # `python -c SCRIPT`: the script's start is enough to recognise it
        words[2:3] = [words[2][:40] + "…" if len(words[2]) > 40 else words[2]] if len(words) > 2 else []
    text = " ".join(shlex.join(words).split())  # one line, whatever the arguments hold
    return text if len(text) <= COMMAND_CHARS else text[: COMMAND_CHARS - 1] + "…"


def _start_ticks(pid: int) -> int | None:
    """When ``pid`` started, in clock ticks since boot (/proc/PID/stat field 22): a pid that
    was reused by a newer process starts later."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return int(f.read().rsplit(b")", 1)[1].split()[19])
    except (OSError, IndexError, ValueError):
        return None


@dataclass(frozen=True)
class Holder:
    pid: int
    command: str
    host: str
    since: float | None  # time.time() of the claim; None when not known (a port's user found in /proc)
    started: int | None = None  # the process's start (_start_ticks): tells a reused pid apart

    @classmethod
    def me(cls) -> "Holder":
        pid = os.getpid()
        return cls(
            pid,
            typed_command(getattr(sys, "orig_argv", sys.argv)),
            socket.gethostname(),
            time.time(),
            _start_ticks(pid),
        )

    def since_text(self) -> str | None:
        if self.since is None:
            return None
        when = time.localtime(self.since)
        same_day = time.strftime("%Y-%m-%d", when) == time.strftime("%Y-%m-%d")
        return time.strftime("%H:%M:%S" if same_day else "%Y-%m-%d %H:%M:%S", when)

    def elsewhere(self) -> str:
        return "" if self.host == socket.gethostname() else f"on host {self.host}"

    def describe(self) -> str:
        """``pid 4242 (rig console --config rig-sim.toml) since 13:05:02``."""
        since = self.since_text()
        text = f"pid {self.pid} ({self.command})" + (f" since {since}" if since else "")
        return text + (f" {self.elsewhere()}" if self.elsewhere() else "")

    def alive(self) -> bool | None:
        """Whether the process still runs; None when it ran on another host."""
        if self.elsewhere():
            return None
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            pass  # another user's: it exists
        return self.started is None or _start_ticks(self.pid) in (None, self.started)

    def busy(self, device: str, roles: str, subject: str = "device") -> DeviceBusy:
        return DeviceBusy(
            device,
            roles,
            pid=self.pid,
            command=self.command,
            since=self.since_text(),
            detail=self.elsewhere(),
            subject=subject,
        )

    def record(self, device: str, roles: str) -> bytes:
        data = json.dumps({**asdict(self), "device": device, "roles": roles}, ensure_ascii=False).encode()
        return data[: RECORD_BYTES - 1].ljust(RECORD_BYTES - 1) + b"\n"


def parse_record(data: bytes) -> tuple[Holder, str, str | None] | None:
    """(holder, the roles it holds the device for, the device it names) from a lock file; None
    when it is empty (released) or not written yet."""
    try:
        fields = json.loads(data.decode().strip() or "null")
        pid, since, started = fields["pid"], fields["since"], fields.get("started")
        if not (isinstance(pid, int) and pid > 0):
            return None  # a hand-edited file: no process to name (and pid 0 would be a process group)
        since = float(since) if isinstance(since, (int, float)) and math.isfinite(since) else None
        started = started if isinstance(started, int) else None
        device = fields.get("device")
        return (
            Holder(pid, str(fields["command"]), str(fields["host"]), since, started),
            str(fields.get("roles", "")),
            device if isinstance(device, str) else None,
        )
    except (ValueError, TypeError, KeyError, UnicodeDecodeError, RecursionError):
        return None


def _record_of(path: Path) -> tuple[Holder, str, str | None] | None:
    """The record in a lock file that another process has locked, waiting briefly for it
    (the holder writes it right after locking)."""
    deadline = time.monotonic() + RECORD_WAIT_S
    pause = threading.Event()
    while True:
        try:
            fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC | os.O_NONBLOCK)
            try:
                record = parse_record(os.pread(fd, RECORD_BYTES, 0))
            finally:
                os.close(fd)
        except OSError:
            record = None
        if record is not None or time.monotonic() >= deadline:
            return record
        pause.wait(0.005)  # a polling wait on the record appearing, bounded by the deadline


def port_user(path: str) -> Holder | None:
    """A process that has ``path`` open, from /proc (this user's processes; any as root)."""
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        with contextlib.suppress(OSError):
            for fd in os.scandir(f"/proc/{entry.name}/fd"):
                with contextlib.suppress(OSError):
                    if os.readlink(fd.path) == path:
                        pid = int(entry.name)
                        argv = Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace").split("\0")
                        return Holder(pid, typed_command([w for w in argv if w]), socket.gethostname(), None)
    return None


# -- claims ----------------------------------------------------------------------------------
def _open_lock_file(path: Path) -> int:
    """Open (or create) a lock file without following a link, and only if it is a plain file of
    this user's with one name: a link planted in its place would have this process truncate and
    write another file (O_NOFOLLOW refuses it), a hard link would do the same to the file it
    shares. RigError naming the file otherwise; nothing is written to it."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW | os.O_NONBLOCK, 0o600)
    except OSError as exc:
        why = "it is a symbolic link" if exc.errno == errno.ELOOP else exc.strerror
        raise RigError(f"lock file {path}: cannot open it ({why}); remove it and try again") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode) or st.st_uid != os.getuid() or st.st_nlink != 1:
        os.close(fd)
        what = (
            "not a plain file"
            if not stat.S_ISREG(st.st_mode)
            else ("another user's" if st.st_uid != os.getuid() else f"a file with {st.st_nlink} names (a hard link)")
        )
        raise RigError(f"lock file {path}: {what}; remove it and try again (nothing was written to it)")
    return fd


def _take(folder: Path, endpoint: str, roles: str, me: Holder, subject: str) -> tuple[int, str | None]:
    """Lock ``endpoint``'s file and write ``me`` into it: (fd, the stale-lock note or None)."""
    path = lock_path(endpoint, folder)
    fd = _open_lock_file(path)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
            raise RigError(f"lock file {path}: cannot lock it ({exc.strerror})") from None
        record = _record_of(path)
        if record is None:
            raise DeviceBusy(endpoint, roles, detail="(its record is not written yet)", subject=subject) from None
        holder, its_roles, its_device = record
        if its_device not in (None, endpoint):  # a record copied or moved in from another lock file
            raise DeviceBusy(
                endpoint, roles, detail=f"(its lock file {path} names {its_device}: check {path})", subject=subject
            ) from None
        raise holder.busy(endpoint, its_roles or roles, subject) from None  # the roles it holds the device for
    try:
        record = parse_record(os.pread(fd, RECORD_BYTES, 0))
        os.pwrite(fd, me.record(endpoint, roles), 0)
    except OSError as exc:
        _let_go(fd)
        raise RigError(f"lock file {path}: cannot write it ({exc.strerror})") from None
    if record is None:
        return fd, None
    before, its_roles, _ = record
    alive = before.alive()
    why = {
        False: "that process is gone",
        True: f"pid {before.pid} runs but no longer holds it",
        None: "taken on another host, whose lock this one cannot see",
    }[alive]
    return fd, f"stale lock on {endpoint} ({its_roles or roles}) of {before.describe()} taken over: {why}"


def _let_go(fd: int) -> None:
    """Empty the record (a clean release: the next claim has nothing to report) and unlock."""
    with contextlib.suppress(OSError):
        os.ftruncate(fd, 0)
    with contextlib.suppress(OSError):
        fcntl.flock(fd, fcntl.LOCK_UN)
    os.close(fd)


class Claim:
    """The endpoints this process holds, each with the roles that use it. ``release()`` (or
    leaving ``with``) lets them go; ``notes``: one line per stale lock taken over."""

    def __init__(self, holder: Holder, held: dict[str, tuple[str, int]], notes: list[str]):
        self.holder = holder
        self._held = held  # endpoint -> (roles, fd)
        self.notes = notes
        self._owner = os.getpid()  # a forked child must not unlock its parent's claim

    @property
    def endpoints(self) -> dict[str, str]:
        """Endpoint → roles ("axes x, y, z"), sorted by endpoint."""
        return {endpoint: roles for endpoint, (roles, _) in self._held.items()}

    def devices_text(self) -> str:
        """``/dev/pts/0 (axes x, y, z), /dev/pts/2 (gauge)``."""
        return ", ".join(f"{endpoint} ({roles})" for endpoint, roles in self.endpoints.items()) or "no devices"

    def holder_line(self) -> str:
        """``pid 4242 (rig console --config rig-sim.toml) since 13:05:02 holds /dev/pts/0 (axes x, y, z)``."""
        return f"{self.holder.describe()} holds {self.devices_text()}"

    def release(self) -> None:
        held, self._held = self._held, {}
        for _, fd in held.values():
            if os.getpid() == self._owner:
                _let_go(fd)
            else:
                os.close(fd)

    @contextlib.contextmanager
    def explaining(self) -> Iterator[None]:
        """A port's own lock refusing (a transport's ``DeviceBusy``, which knows no claims) is
        told as a claim's refusal: the roles using the port and, where /proc shows it, the
        process that has it open."""
        try:
            yield
        except DeviceBusy as exc:
            if exc.pid is not None:
                raise
            endpoint = serial_endpoint(exc.device) or exc.device
            roles = self._held.get(endpoint, (exc.roles, 0))[0]
            holder = port_user(endpoint)
            if holder is None:
                raise DeviceBusy(endpoint, roles, detail=exc.detail) from None
            raise holder.busy(endpoint, roles) from None

    def __enter__(self) -> "Claim":
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    def __del__(self) -> None:  # a claim dropped unreleased (a leaked rig) lets go when collected
        with contextlib.suppress(Exception):
            self.release()


def claim(uses: Mapping[str, Iterable[str]], *, subject: str = "device") -> Claim:
    """Claim every endpoint of ``uses`` (endpoint → roles) or none: DeviceBusy naming the
    first one held elsewhere. Stale locks are taken over, each noted in one line."""
    me = Holder.me()
    held: dict[str, tuple[str, int]] = {}
    notes: list[str] = []
    try:
        folder = runtime_dir() if uses else Path()
        for endpoint in sorted(uses):  # one order for every process: two never hold a part each
            roles = roles_text(uses[endpoint])
            fd, note = _take(folder, endpoint, roles, me, subject)
            held[endpoint] = (roles, fd)
            if note:
                log.warning(note)
                notes.append(note)
    except BaseException:
        for _, fd in held.values():
            _let_go(fd)
        raise
    return Claim(me, held, notes)


def claim_rig(config: RigConfig, axes: Iterable[str], *, gauge: bool, camera: bool) -> Claim:
    """Claim the devices ``Rig.open`` is about to open."""
    return claim(rig_endpoints(config, axes, gauge=gauge, camera=camera))
