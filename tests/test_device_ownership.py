"""One owner per device (rig/ownership.py, rig/transport/exclusive.py), over real ptys and
sockets, with real processes: nothing about the locking is mocked.

The simulators run in their own process (`rig sim serve`), as hardware would; a first process
holds the rig and keeps reading the gauge; a second one (`rig jog`, `rig zero`, `rig console`,
`rig sim serve`) must be refused in one line naming the holder, and must not disturb it.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import socket
import subprocess
import sys
import textwrap
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest
from processes import stop

from rig import ownership
from rig.errors import DeviceBusy, RigError
from rig.transport import exclusive
from rig.transport.serial_link import SerialLink

RIG = str(Path(sys.executable).parent / "rig")
DEADLINE_S = 60.0

# A process that holds the rig and reads the gauge until told to stop; `report` prints what it
# saw: samples read, errors, positions. Run as a file, so its command line reads `python holder.py`.
HOLDER = textwrap.dedent(
    """
    import json, sys, threading
    from rig.config import load_config
    from rig.rig import Rig

    axes = tuple(a for a in sys.argv[2].split(",") if a)
    rig = Rig.open(load_config(sys.argv[1]), axes=axes)
    seen = {"samples": 0, "errors": []}
    stop = threading.Event()

    def read():
        while not stop.is_set():
            try:
                rig.gauge.read_fresh()
                seen["samples"] += 1
            except Exception as exc:
                seen["errors"].append(f"{type(exc).__name__}: {exc}")

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    print("holding", flush=True)
    for line in sys.stdin:
        if line.strip() != "report":
            break
        print(json.dumps({**seen, "positions": rig.positions()}), flush=True)
    stop.set()
    reader.join(5)
    rig.close()
    """
)


_stop = stop


def line_matching(proc: subprocess.Popen, prefix: str) -> str:
    """The first line of ``proc``'s stdout starting with ``prefix`` (fails if it ends first)."""
    assert proc.stdout is not None
    for line in proc.stdout:
        if line.startswith(prefix):
            return line
    raise AssertionError(
        f"{proc.args[:4]} ended without printing {prefix!r}: {proc.stderr.read() if proc.stderr else ''}"
    )


@contextlib.contextmanager
def served(folder: Path, *options: str, name: str = "sim.toml") -> Iterator[tuple[Path, subprocess.Popen]]:
    """`rig sim serve --out FOLDER/NAME OPTIONS` running: (its config, its process)."""
    cfg = folder / name
    proc = subprocess.Popen(
        [RIG, "sim", "serve", "--out", str(cfg), *options], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        line_matching(proc, "serving")
        yield cfg, proc
    finally:
        _stop(proc)


class Holder:
    """A process holding the rig of ``cfg`` (``axes``: which; the gauge always) and reading its gauge."""

    def __init__(self, folder: Path, cfg: Path, axes: str = "x,y,z,theta"):
        script = folder / "holder.py"
        script.write_text(HOLDER)
        self.proc = subprocess.Popen(
            [sys.executable, str(script), str(cfg), axes],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.pid = self.proc.pid
        line_matching(self.proc, "holding")

    def report(self) -> dict:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write("report\n")
        self.proc.stdin.flush()
        return json.loads(self.proc.stdout.readline())

    def samples_beyond(self, count: int, more: int = 20) -> dict:
        """Report once ``more`` samples beyond ``count`` were read (polled until a deadline)."""
        deadline = time.monotonic() + DEADLINE_S
        while True:
            seen = self.report()
            if seen["samples"] >= count + more or time.monotonic() > deadline:
                return seen

    def close(self) -> None:
        if self.proc.poll() is None:
            assert self.proc.stdin is not None
            self.proc.stdin.write("quit\n")
            self.proc.stdin.flush()
            self.proc.wait(timeout=30)


@contextlib.contextmanager
def holding(folder: Path, cfg: Path, axes: str = "x,y,z,theta") -> Iterator[Holder]:
    holder = Holder(folder, cfg, axes)
    try:
        yield holder
    finally:
        holder.close()
        _stop(holder.proc)


def rig_cmd(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([RIG, *args], capture_output=True, text=True, timeout=DEADLINE_S)


def refusal(result: subprocess.CompletedProcess) -> str:
    """The one-line error of a refused command."""
    assert result.returncode == 1, (result.returncode, result.stdout, result.stderr)
    assert "Traceback" not in result.stderr, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    return lines[0]


def dead_pid() -> int:
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    return int(done.stdout)


def write_stale_lock(endpoint: str, roles: str, pid: int) -> Path:
    """The lock file a holder killed with SIGKILL leaves: its record, no lock."""
    path = ownership.lock_path(endpoint)
    holder = ownership.Holder(pid, "rig console --config gone.toml", socket.gethostname(), time.time() - 60)
    path.write_bytes(holder.record(endpoint, roles))
    return path


def config_keys(cfg: Path) -> dict:
    import tomllib

    return tomllib.loads(cfg.read_text())


@pytest.mark.slow
def test_a_jog_is_refused_while_another_process_holds_the_rig(tmp_path):
    """Over ptys: the stale lock of a killed holder is taken over and said so; then, while a
    process holds the rig, `rig jog` is refused naming it, y does not move, and the holder's
    gauge stream goes on; once it has let go, the jog works again."""
    from rig.config import load_config

    with served(tmp_path) as (cfg, _server):
        config = load_config(cfg)
        stages = ownership.serial_endpoint(config.axes["y"].port)
        assert stages == os.path.realpath(config.axes["y"].port)
        uses = ownership.rig_endpoints(config, config.axes, gauge=True, camera=True)
        assert uses[stages] == ["axis x", "axis y", "axis z"]  # the daisy chain: one claim

        gone = dead_pid()
        stale = write_stale_lock(stages, "axes x, y, z", gone)
        result = rig_cmd("jog", "--axis", "y", "--step", "0.2", "--config", str(cfg))
        assert result.returncode == 0, result.stderr
        notes = [line for line in result.stderr.splitlines() if line.startswith("stale lock")]
        assert len(notes) == 1, result.stderr
        assert notes[0].startswith(
            f"stale lock on {stages} (axes x, y, z) of pid {gone} (rig console --config gone.toml) since "
        )
        assert notes[0].endswith(" taken over: that process is gone"), notes
        assert result.stdout.strip() == "y = 0.2000 mm"
        assert stale.exists() and stale.read_bytes() == b""  # released cleanly: emptied, not deleted

        with holding(tmp_path, cfg) as holder:
            before = holder.report()
            assert before["positions"]["y"] == pytest.approx(0.2, abs=1e-3)
            line = refusal(rig_cmd("jog", "--axis", "y", "--step", "0.2", "--config", str(cfg)))
            gauge = ownership.gauge_endpoint(config.gauge)  # the jog needs the gauge too: the first held is named
            assert any(
                line.startswith(f"error: device {device} is held by pid {holder.pid} (python ")
                for device in (f"{stages} (axes x, y, z)", f"{gauge} (gauge)")
            ), line
            assert "holder.py" in line and " since " in line and line.endswith("stop that process first")
            after = holder.samples_beyond(before["samples"])
            assert after["samples"] >= before["samples"] + 20, after  # its stream goes on
            assert after["errors"] == [], after["errors"]
            assert after["positions"]["y"] == pytest.approx(0.2, abs=1e-3)  # y did not move

        result = rig_cmd("jog", "--axis", "y", "--step", "0.2", "--config", str(cfg))
        assert result.returncode == 0, result.stderr
        assert "stale lock" not in result.stderr  # the holder let go cleanly
        assert float(result.stdout.split()[2]) == pytest.approx(0.4, abs=1e-3), result.stdout


def _messages(ws, until, what: str) -> list[dict]:
    """JSON messages from a console's WebSocket until ``until(messages)`` holds (frames skipped)."""
    seen: list[dict] = []
    deadline = time.monotonic() + DEADLINE_S
    while not until(seen):
        assert time.monotonic() < deadline, f"{what}: not seen in {DEADLINE_S} s; got {[m.get('type') for m in seen]}"
        message = ws.recv(timeout=DEADLINE_S)
        if not isinstance(message, bytes):
            seen.append(json.loads(message))
    return seen


def _rig_message(messages: list[dict]) -> dict | None:
    return next((m for m in reversed(messages) if m.get("type") == "rig"), None)


@contextlib.contextmanager
def console_process(cfg: Path, runs: Path) -> Iterator[tuple[subprocess.Popen, int]]:
    proc = subprocess.Popen(
        [RIG, "console", "--config", str(cfg), "--port", "0", "--runs", str(runs)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = line_matching(proc, "console at http://127.0.0.1:")
        yield proc, int(line.split("127.0.0.1:")[1].split("/")[0])
    finally:
        _stop(proc)


@pytest.mark.slow
def test_a_second_console_shows_who_holds_the_rig_and_the_first_streams_on(tmp_path):
    """Over sockets (`--transport tcp`): two `rig console` on one config, as in issue 24. The
    second cannot open the rig and its page is told who holds it; `rig jog` is refused naming
    the first console; the first console's page keeps receiving the gauge and y stays put."""
    websockets_sync = pytest.importorskip("websockets.sync.client")
    with served(tmp_path, "--transport", "tcp") as (cfg, _server), console_process(cfg, tmp_path) as (first, port1):
        with websockets_sync.connect(f"ws://127.0.0.1:{port1}/ws", open_timeout=DEADLINE_S) as ws1:
            opened = _messages(ws1, lambda ms: (_rig_message(ms) or {}).get("state") == "open", "the first rig open")
            mine = _rig_message(opened)
            assert mine is not None and mine["pid"] == first.pid and "axes x, y, z" in mine["devices"]
            with console_process(cfg, tmp_path) as (second, port2):
                with websockets_sync.connect(f"ws://127.0.0.1:{port2}/ws", open_timeout=DEADLINE_S) as ws2:
                    told = _messages(ws2, lambda ms: (_rig_message(ms) or {}).get("state") == "busy", "busy")
                busy = _rig_message(told)
                assert busy is not None and busy["holder_pid"] == first.pid, busy
                assert busy["holder_command"].startswith("rig console --config "), busy
                assert f"is held by pid {first.pid} (rig console --config " in busy["error"]
                with urllib.request.urlopen(f"http://127.0.0.1:{port2}/api/info", timeout=DEADLINE_S) as answer:
                    info = json.load(answer)
                assert info["rig"]["state"] == "busy" and info["rig"]["holder_pid"] == first.pid
                assert second.poll() is None  # the second console serves on, saying why it has no rig

                line = refusal(rig_cmd("jog", "--axis", "y", "--step", "0.2", "--config", str(cfg)))
                assert f"is held by pid {first.pid} (rig console --config " in line, line

            # the first console's gauge stream goes on: 50 more samples, no error event, y unmoved
            def streamed(ms: list[dict]) -> bool:
                return sum(len(m.get("wrench", [])) for m in ms if m.get("type") == "state") >= 50

            later = _messages(ws1, streamed, "50 wrench samples on the first console")
            errors = [m["text"] for m in later if m.get("type") == "event" and m.get("level") == "error"]
            assert errors == [], errors
            states = [m for m in later if m.get("type") == "state" and m["axes"]]
            assert states and states[-1]["axes"]["y"]["position"] == pytest.approx(0.0, abs=1e-3)


@pytest.mark.slow
def test_the_ati_netft_endpoint_is_claimed(tmp_path):
    """The Net F/T speaks UDP: its claim is the box's host and RDT port."""
    with served(tmp_path, "--gauge", "ati_netft") as (cfg, _server):
        gauge = config_keys(cfg)["gauge"]
        endpoint = f"127.0.0.1:{gauge['rdt_port']}/udp"
        with holding(tmp_path, cfg, axes="") as holder:
            before = holder.report()
            line = refusal(rig_cmd("zero", "--samples", "5", "--config", str(cfg)))
            assert line.startswith(f"error: device {endpoint} (gauge) is held by pid {holder.pid} (python "), line
            after = holder.samples_beyond(before["samples"])
            assert after["samples"] >= before["samples"] + 20 and after["errors"] == [], after


@pytest.mark.slow
def test_a_second_sim_serve_on_the_same_out_is_refused(tmp_path):
    with served(tmp_path) as (cfg, first):
        text = cfg.read_text()
        result = subprocess.run(
            [RIG, "sim", "serve", "--out", str(cfg)], capture_output=True, text=True, timeout=DEADLINE_S
        )
        line = refusal(result)
        where = os.path.realpath(cfg)
        assert line.startswith(
            f"error: config {where} (rig sim serve --out) is held by pid {first.pid} (rig sim serve --out "
        ), line
        assert first.poll() is None and cfg.read_text() == text  # the first serves on, its config untouched


# -- in this process: the claims and the port locks themselves -------------------------------
def test_endpoints_are_written_one_way(tmp_path):
    master, slave = os.openpty()
    try:
        link = tmp_path / "by-id-link"
        link.symlink_to(os.ttyname(slave))
        assert ownership.serial_endpoint(str(link)) == os.path.realpath(os.ttyname(slave))
    finally:
        os.close(master)
        os.close(slave)
    assert ownership.serial_endpoint("socket://localhost:4001") == "127.0.0.1:4001"
    assert ownership.serial_endpoint("rfc2217://RigBox.lan:4002?logging=debug") == "rigbox.lan:4002"
    assert ownership.serial_endpoint("loop://") is None
    assert ownership.host_port("::1", 49152, "udp") == "[::1]:49152/udp"
    assert ownership.roles_text(["axis x", "axis y", "gauge"]) == "axes x, y, gauge"
    assert ownership.roles_text(["axis theta"]) == "axis theta"


def test_a_claim_refuses_a_second_and_takes_over_a_stale_lock(tmp_path, caplog):
    master, slave = os.openpty()
    endpoint = os.path.realpath(os.ttyname(slave))
    try:
        gone = dead_pid()
        path = write_stale_lock(endpoint, "axis x", gone)
        with caplog.at_level("WARNING", logger="rig.ownership"):
            first = ownership.claim({endpoint: ["axis x"]})
        try:
            assert len(first.notes) == 1 and first.notes[0].startswith(
                f"stale lock on {endpoint} (axis x) of pid {gone}"
            )
            assert first.notes[0].endswith("taken over: that process is gone")
            assert [r.getMessage() for r in caplog.records] == first.notes
            assert f"pid {os.getpid()} (" in first.holder_line() and f"{endpoint} (axis x)" in first.holder_line()
            with pytest.raises(DeviceBusy) as refused:
                ownership.claim({endpoint: ["axis y"]})  # flock is per open file: this process too
            assert refused.value.pid == os.getpid()
            assert str(refused.value).startswith(f"device {endpoint} (axis x) is held by pid {os.getpid()} (")
        finally:
            first.release()
        assert path.exists() and path.read_bytes() == b""  # not deleted: emptied and unlocked
        with ownership.claim({endpoint: ["axis x"]}) as again:
            assert again.notes == []
    finally:
        os.close(master)
        os.close(slave)


def test_a_serial_port_is_locked_on_its_node(tmp_path):
    """Without any claim (another user's process, another program using pyserial's lock), a
    second open of the port is refused, and a claim's explanation names the process holding it."""
    master, slave = os.openpty()
    port = os.ttyname(slave)
    first = SerialLink(port, baudrate=115200, timeout_s=0.2, device="first")
    try:
        with pytest.raises(DeviceBusy, match="locked its node"):
            SerialLink(port, baudrate=115200, timeout_s=0.2, device="second")
        with ownership.claim({os.path.realpath(port): ["axis x"]}) as claim:
            with pytest.raises(DeviceBusy) as refused, claim.explaining():
                SerialLink(port, baudrate=115200, timeout_s=0.2, device="second")
        assert str(refused.value).startswith(f"device {os.path.realpath(port)} (axis x) is held by pid {os.getpid()} (")
        first.close()
        SerialLink(port, baudrate=115200, timeout_s=0.2, device="third").close()  # closed: free again
    finally:
        first.close()
        os.close(master)
        os.close(slave)


def _open_as_nobody(path: str) -> str:
    """'opened' or the error of opening ``path`` as an unprivileged user (TIOCEXCL binds them)."""
    code = (
        f"import os\ntry:\n os.close(os.open({path!r}, os.O_RDWR | os.O_NOCTTY)); print('opened')\n"
        "except OSError as e:\n print(e.errno)"
    )
    if os.geteuid() != 0:
        return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.strip()
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv: cannot open the tty as another user")
    as_nobody = [setpriv, "--reuid=65534", "--regid=65534", "--clear-groups", sys.executable, "-c", code]
    return subprocess.run(as_nobody, capture_output=True, text=True).stdout.strip()


def test_tiocexcl_keeps_other_opens_out_and_is_cleared(tmp_path):
    import errno

    master, slave = os.openpty()
    path = os.ttyname(slave)
    os.chmod(path, 0o666)
    try:
        assert exclusive.is_pty_slave(slave)
        assert exclusive.hold(slave) is False  # not on a pty: a killed holder would lock it until the master closes
        assert _open_as_nobody(path) == "opened"
        assert exclusive.hold(slave, on_pty=True) is True  # what a real tty gets
        assert _open_as_nobody(path) == str(errno.EBUSY)
        exclusive.let_go(slave)
        assert _open_as_nobody(path) == "opened"
    finally:
        os.close(master)
        os.close(slave)


# -- lock files that another user could plant -------------------------------------------------
def test_a_symlinked_lock_file_leaves_its_target_untouched(tmp_path, monkeypatch):
    folder = tmp_path / "runtime"
    folder.mkdir(mode=0o700)
    monkeypatch.setenv("TACTILE_RUNTIME_DIR", str(folder))
    target = tmp_path / "someone-elses-file"
    target.write_text("precious\n")
    endpoint = "127.0.0.1:4999"
    ownership.lock_path(endpoint).symlink_to(target)
    with pytest.raises(RigError, match=r"cannot open it \(it is a symbolic link\)"):
        ownership.claim({endpoint: ["axis z"]})
    assert target.read_text() == "precious\n"
    ownership.lock_path(endpoint).unlink()
    os.link(target, ownership.lock_path(endpoint))  # a hard link: the same file under two names
    with pytest.raises(RigError, match="hard link"):
        ownership.claim({endpoint: ["axis z"]})
    assert target.read_text() == "precious\n"


@pytest.mark.parametrize("mode", [0o777, 0o755, 0o1777])
def test_a_lock_folder_others_can_enter_is_refused_in_one_line(tmp_path, monkeypatch, mode):
    folder = tmp_path / "runtime"
    folder.mkdir()
    folder.chmod(mode)
    monkeypatch.setenv("TACTILE_RUNTIME_DIR", str(folder))
    with pytest.raises(RigError, match=rf"mode {mode & 0o7777:04o} lets other users in; `chmod 700"):
        ownership.claim({"127.0.0.1:4999": ["gauge"]})
    link = tmp_path / "link"
    link.symlink_to(folder)
    monkeypatch.setenv("TACTILE_RUNTIME_DIR", str(link))
    with pytest.raises(RigError, match="not a folder owned by"):
        ownership.claim({"127.0.0.1:4999": ["gauge"]})


def test_a_busy_message_names_the_device_its_record_is_of(tmp_path, monkeypatch):
    """A record copied in from another lock file names another device: the refusal says so instead
    of blaming the holder for the wrong device."""
    folder = tmp_path / "runtime"
    folder.mkdir(mode=0o700)
    monkeypatch.setenv("TACTILE_RUNTIME_DIR", str(folder))
    held = ownership.claim({"127.0.0.1:4001": ["axis x"]})
    try:
        os.rename(ownership.lock_path("127.0.0.1:4001"), ownership.lock_path("127.0.0.1:4002"))
        with pytest.raises(DeviceBusy, match=r"its lock file .* names 127.0.0.1:4001"):
            ownership.claim({"127.0.0.1:4002": ["gauge"]})
    finally:
        held.release()
