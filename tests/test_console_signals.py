"""SIGTERM and SIGHUP to `rig console` while the page's jog moves a stage: every axis stops.

The simulators run in another process (`rig sim serve`), as hardware would, so that what
the stages do after the console process ends can be read back with `rig status`.
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

websockets_sync = pytest.importorskip("websockets.sync.client")

RIG = str(Path(sys.executable).parent / "rig")
DEADLINE_S = 60.0


def _line_matching(proc: subprocess.Popen, pattern: str) -> re.Match:
    assert proc.stdout is not None
    for line in proc.stdout:
        found = re.search(pattern, line)
        if found:
            return found
    raise AssertionError(
        f"{proc.args[:3]} ended without printing {pattern!r}: {proc.stderr.read() if proc.stderr else ''}"
    )


def _x_of_status(cfg: Path) -> tuple[float, str]:
    out = subprocess.run([RIG, "status", "--config", str(cfg)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    # the status table's row: "│ x     │ -0.0000  │ mm   │ idle  │ ..."
    line = next(line for line in out.stdout.splitlines() if line.replace("│", " ").split()[:1] == ["x"])
    found = re.search(r"[-+]\d+\.\d+", line)
    assert found, line
    return float(found.group()), line


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_a_signal_to_the_console_stops_the_jog_in_progress(tmp_path, signum):
    cfg = tmp_path / "sim.toml"
    server = subprocess.Popen(
        [RIG, "sim", "serve", "--out", str(cfg), "--transport", "tcp"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    console = None
    try:
        _line_matching(server, r"^serving")
        x0, _ = _x_of_status(cfg)
        console = subprocess.Popen(
            [RIG, "console", "--config", str(cfg), "--port", "0", "--runs", str(tmp_path)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        port = int(_line_matching(console, r"console at http://127\.0\.0\.1:(\d+)/")[1])
        with websockets_sync.connect(f"ws://127.0.0.1:{port}/ws", open_timeout=DEADLINE_S) as ws:
            ws.send(json.dumps({"type": "take_control"}))
            ws.send(json.dumps({"type": "jog", "axis": "x", "step": 10.0}))  # 10 s at the 1 mm/s jog speed
            deadline = time.monotonic() + DEADLINE_S
            while True:  # until the page's state shows x moving
                assert time.monotonic() < deadline, "x never started moving"
                message = ws.recv(timeout=DEADLINE_S)
                if isinstance(message, bytes):
                    continue  # a frame
                state = json.loads(message)
                if state.get("type") == "state" and state["axes"].get("x", {}).get("state") == "busy":
                    break
            console.send_signal(signum)
        assert console.wait(timeout=DEADLINE_S) is not None
        x_after, line = _x_of_status(cfg)
        x_later, line_later = _x_of_status(cfg)
        assert "idle" in line_later, line_later
        assert x_later == pytest.approx(x_after, abs=1e-4), "x kept moving after the console ended"
        assert x0 < x_later < x0 + 10.0 - 1.0, f"x stopped at {x_later}, started at {x0}: not mid-jog"
    finally:
        for proc in (console, server):
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    proc.kill()
