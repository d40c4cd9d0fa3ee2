"""The one thread that owns the rig for the console.

The devices are blocking (serial exchanges, a camera grabber), the web server is async: this
thread opens the rig, takes commands from a queue and hands snapshots back through callbacks
(the server wraps them in ``loop.call_soon_threadsafe``). Every move goes through the guarded
motion session (rig/motion.py) exactly as ``rig jog`` does; a move is started and then
monitored here, poll by poll, so that a stop command (or the console closing) stops it
between two safety checks instead of after the move. A protocol started from the page runs through
cli/console/worker_protocol.py, a jog or a homing through cli/console/worker_moves.py.
"""

from __future__ import annotations

import contextlib
import logging
import os
import queue
import threading
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cli.console.worker_moves import Moving
from cli.console.worker_protocol import HISTORY_S, ProtocolRunning, tare_state
from common.errors import ToolError
from rig.errors import DeviceBusy, DeviceTimeout

log = logging.getLogger("rig.console")

STATUS_EVERY_S = 0.1  # axis positions and states: 4 exchanges per 100 ms leave the links mostly free
WRENCH_EVERY_S = 0.02  # the live trace keeps a sample per 20 ms: 3000 points for the last minute
IDLE_TICK_S = 0.01  # how long the idle loop waits for a command before looking for a new frame
JPEG_QUALITY = 85  # a 256 px frame is ~10 kB: fine on any link, gel texture still visible
TARE_SAMPLES = 50  # as `rig zero`


@dataclass(frozen=True)
class Command:
    """What a browser asked for: ``jog`` (axis, step), ``stop``, ``home`` (axis or all), ``zero``,
    ``protocol`` (a library protocol's name, the contact origin x, y, z, theta and --set values)."""

    kind: str
    axis: str | None = None
    step: float | None = None
    who: str = ""
    name: str = ""
    origin: tuple[float, float, float, float] | None = None
    settings: tuple[str, ...] = ()


@dataclass(frozen=True)
class FrameOut:
    """One encoded camera frame for the browsers: index, capture time on the rig clock (s)."""

    index: int
    t_s: float
    width: int
    height: int
    jpeg: bytes


def rig_status(state: str, rig: Any = None, error: BaseException | None = None) -> dict:
    """What the page shows about the rig: ``opening``, ``open`` (this console, pid N, holds its
    devices), ``busy`` (another process holds one: its pid and command), ``failed``, ``closed``."""
    status: dict[str, Any] = {"type": "rig", "state": state, "pid": os.getpid()}
    claim = getattr(rig, "claim", None)
    if claim is not None:
        status.update(devices=claim.devices_text(), holder=claim.holder_line())
    if error is not None:
        status["error"] = str(error) if isinstance(error, ToolError) else f"{type(error).__name__}: {error}"
    if isinstance(error, DeviceBusy):
        status.update(
            device=error.device,
            roles=error.roles,
            holder_pid=error.pid,
            holder_command=error.command,
            holder_since=error.since,
        )
    return status


@contextlib.contextmanager
def open_console_rig(config: Path | None, sim: bool, sensor: str = "rgb") -> Iterator[tuple[Any, Any]]:
    """Yield (rig, simulated rig or None): every configured device, the camera when configured;
    ``sensor``: the kind the simulated camera renders (common/sensors.py).

    Like ``cli.session.open_rig`` but without signal handlers (this runs outside the main
    thread, where Python cannot install them; uvicorn's own handlers stop the server,
    and closing the worker stops any move).
    """
    from cli.session import resolve_config_path
    from rig.config import load_config
    from rig.rig import Rig

    if sim:
        from cli.console.protocol_run import SIM_INDENTER
        from rig.sim.rig_sim import SimulatedRig

        with SimulatedRig(sensor_kind=sensor, indenter=SIM_INDENTER) as simulated:
            cfg = simulated.config()
            with Rig.open(cfg, simulated.clock, camera=True, sim=simulated) as rig:
                yield rig, simulated
    else:
        cfg = load_config(resolve_config_path(config))
        with Rig.open(cfg, camera=cfg.camera is not None) as rig:
            yield rig, None


class RigWorker(ProtocolRunning, Moving):
    """Owns the rig in its own thread. ``submit`` commands; snapshots arrive through
    ``on_state(dict)``, ``on_event(level, text)`` and ``on_frame(FrameOut)``, called from
    this thread."""

    def __init__(
        self,
        opener: Callable[[], contextlib.AbstractContextManager[tuple[Any, Any]]],
        *,
        on_state: Callable[[dict], object],
        on_event: Callable[[str, str], object],
        on_frame: Callable[[FrameOut], object],
        sensor: str = "rgb",
        runs_folder: Path = Path("runs"),
        simulated: bool = False,
    ):
        self._opener = opener
        self.sensor = sensor  # the camera's sensor kind: a protocol started here must be for it
        self.simulated = simulated  # the console's own simulated rig (--sim): its indenter is fixed
        self.runs_folder = runs_folder  # where a protocol started here writes its run file
        self._run_stop: Any = None  # the StopRequest of the protocol running, if any
        self._run_rig: Any = None  # a protocol's own rig while it runs (--sim), shown in its place
        self._run_info: dict | None = None  # the protocol running: name, run file, newest frame, phase
        self._ended: dict | None = None  # a --sim protocol's own rig as it ended, shown until the next command
        self.commands_done = 0  # commands carried out (or refused by the rig): benchmarks wait on it
        self.connect(on_state=on_state, on_event=on_event, on_frame=on_frame)
        self._commands: queue.Queue[Command | None] = queue.Queue()
        self._closing = threading.Event()
        self.ready = threading.Event()  # set once the rig is open (or failed to open: see ``error``)
        self.error: str | None = None
        self.rig_status: dict = rig_status("opening")  # who holds the rig, for the page
        self.errors_seen = 0  # unexpected errors logged and survived (a bug or a broken device)
        self.rig: Any = None
        self._sim: Any = None
        self._wrench: deque[list[float]] = deque()
        self._new_wrench: list[list[float]] = []
        self._last_wrench_t = -np.inf
        self._last_status_t = -np.inf
        self._axes: dict[str, dict] = {}
        self._reset_trace = False
        self.activity = ""  # what is moving now, for the page
        self.frames_sent = 0
        self.frame_tap: Callable[[int, float, np.ndarray], object] | None = None  # each raw frame (marker flow)
        self._thread = threading.Thread(target=self._run, name="rig-console-worker", daemon=True)

    # -- the server's side ----------------------------------------------------------------
    def connect(
        self,
        *,
        on_state: Callable[[dict], object],
        on_event: Callable[[str, str], object],
        on_frame: Callable[[FrameOut], object],
        on_rig: Callable[[dict], object] = lambda status: None,
    ) -> None:
        """Where snapshots go (called from this worker's thread); set before ``start``."""
        self._on_state = on_state
        self._on_event = on_event
        self._on_frame = on_frame
        self._on_rig = on_rig

    def _set_rig_status(self, status: dict) -> None:
        self.rig_status = status
        self._on_rig(status)

    def start(self) -> None:
        self._thread.start()

    def submit(self, command: Command) -> None:
        self._commands.put(command)

    @property
    def protocol_running(self) -> bool:
        return self._run_stop is not None

    def request_stop(self, who: str) -> None:
        """STOP (any thread): a protocol running ends as after Ctrl-C, a jog stops at its next poll."""
        run_stop = self._run_stop
        if run_stop is not None:
            run_stop.request(f"STOP from {who or 'the console'}")
        self.submit(Command("stop", who=who))

    def close(self, timeout_s: float = 30.0) -> None:
        """Stop any move or protocol, close the rig and end the thread (bounded wait)."""
        self._closing.set()
        run_stop = self._run_stop
        if run_stop is not None:
            run_stop.request("console closing")
        self._commands.put(None)
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    def history(self) -> list[list[float]]:
        """The last minute of [t_s, Fx, Fy, Fz, Mx, My, Mz] (copied; safe from any thread)."""
        return list(self._wrench)

    def now(self) -> float:
        """The rig clock (s): frame times are on it."""
        return self.rig.clock.now() if self.rig is not None else float("nan")

    # -- the thread -----------------------------------------------------------------------
    def _run(self) -> None:
        opened = False
        try:
            with self._opener() as (rig, sim):
                self.rig, self._sim, opened = rig, sim, True
                self._set_rig_status(rig_status("open", rig))
                for note in getattr(rig.claim, "notes", ()):  # stale locks taken over
                    self._on_event("warn", note)
                self.ready.set()
                self._on_event("info", f"rig open: {', '.join(rig.axes) or 'no axes'}; camera {self._camera_name()}")
                self._loop()
        except Exception as exc:  # opening failed (a device held elsewhere: who holds it), or closing did
            self.error = f"{type(exc).__name__}: {exc}" if not isinstance(exc, ToolError) else str(exc)
            log.error("console rig: %s", self.error)
            busy = isinstance(exc, DeviceBusy) and not opened
            self._set_rig_status(rig_status("busy" if busy else "failed", error=exc))
            self._on_event("error", f"rig: {self.error}")
        else:
            self._set_rig_status(rig_status("closed"))
        finally:
            self.rig = None
            self.ready.set()

    def _camera_name(self) -> str:
        return self.rig.camera.name if self.rig.camera is not None else "none"

    def _loop(self) -> None:
        while not self._closing.is_set():
            self._io()
            try:
                command = self._commands.get(timeout=IDLE_TICK_S)
            except queue.Empty:
                continue
            if command is None:
                break
            self._do(command)

    def _do(self, command: Command) -> None:
        if command.kind != "stop":
            self._ended = None  # a new command: the console's own rig again
        try:
            if command.kind == "jog":
                self._jog(command)
            elif command.kind == "home":
                self._home(command)
            elif command.kind == "protocol":
                self._protocol(command)
            elif command.kind == "zero":
                bias = self.rig.tare(TARE_SAMPLES)
                self._on_event("info", "gauge zeroed; bias " + ", ".join(f"{v:+.3f}" for v in bias))
            elif command.kind == "stop":
                self.rig.stop_all()  # nothing of ours is moving; stop anyway, it is what was asked
                self._on_event("info", "stop: every axis stopped")
            else:
                self._on_event("warn", f"unknown command {command.kind!r}")
        except ToolError as exc:  # a refused or failed move: the session already stopped and lifted
            self._on_event("error", f"{command.kind} {command.axis or ''}: {exc}".replace("  ", " "))
        except Exception as exc:
            self.errors_seen += 1
            log.exception("console %s failed", command.kind)
            self._on_event("error", f"{command.kind}: {type(exc).__name__}: {exc}")
        finally:
            self.activity = ""
            self._recover()
            self._publish_state(force=True)
            self.commands_done += 1

    def _recover(self) -> None:
        """After a failed session the camera is closed and the gauge stream stopped (the
        safe state for a command that exits); the console lives on, so reopen both."""
        rig = self.rig
        cfg = rig.config
        if rig.camera is None and cfg.camera is not None:
            from rig.factory import open_camera

            try:
                rig.camera = open_camera(cfg.camera, rig.clock, self._sim)
            except Exception as exc:
                self.errors_seen += 1
                self._on_event("error", f"camera could not be reopened: {exc}")
        gauge = rig.gauge
        if gauge is not None and cfg.gauge is not None and cfg.gauge.mode == "stream":
            if not getattr(gauge, "streaming", True):
                try:
                    gauge.start_stream()
                except Exception as exc:
                    self.errors_seen += 1
                    self._on_event("error", f"gauge stream could not be restarted: {exc}")

    # -- reading ------------------------------------------------------------------------------
    def _io(self) -> None:
        """One round of reading: a new camera frame if there is one, the wrench, and (every
        STATUS_EVERY_S) the axes; publish what changed."""
        self._read_frame()
        self._read_wrench()
        self._publish_state()

    def _read_frame(self) -> None:
        camera = self.rig.camera
        if camera is None:
            return
        try:
            frame = camera.read(timeout_s=0.0)
        except DeviceTimeout:
            return  # no new frame since the last look
        import cv2

        if self.frame_tap is not None:
            self.frame_tap(frame.index, frame.t_s, frame.image)
        ok, buffer = cv2.imencode(".jpg", frame.image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        if not ok:
            self.errors_seen += 1
            log.error("frame %d could not be encoded", frame.index)
            return
        height, width = frame.image.shape[:2]
        self.frames_sent += 1
        self._on_frame(FrameOut(frame.index, frame.t_s, width, height, buffer.tobytes()))

    def _read_wrench(self) -> None:
        if self.rig.gauge is None:
            return
        w = self.rig.gauge.read()
        if w.t_s - self._last_wrench_t < WRENCH_EVERY_S:
            return
        self._last_wrench_t = w.t_s
        row = [w.t_s, *w.as_array().tolist()]
        self._wrench.append(row)
        self._new_wrench.append(row)
        while self._wrench and self._wrench[0][0] < w.t_s - HISTORY_S:
            self._wrench.popleft()

    def _publish_state(self, force: bool = False) -> None:
        rig = self._run_rig or self.rig
        now = rig.clock.now()
        if not force and now - self._last_status_t < STATUS_EVERY_S:
            return
        self._last_status_t = now
        for name, axis in rig.axes.items():
            cfg = rig.config.axes[name]
            s = axis.status()
            self._axes[name] = {
                "position": s.position,
                "unit": cfg.unit,
                "state": s.state.value,
                "homed": s.homed,
                "warnings": list(s.warnings),
                "travel": list(cfg.travel),
            }
        limits = rig.guard.limits.tolist() if rig.guard is not None else None
        axes, source = self._axes, "the protocol's simulated rig" if self._run_rig is not None else "this console's rig"
        if self._ended is not None and self._run_rig is None:
            axes = self._ended["axes"]
            source = (
                f"protocol {self._ended['protocol']}'s own simulated rig as it ended ({self._ended['status']}); "
                "this console's rig did not move: a command shows it again"
            )
        self._on_state(
            {
                "type": "state",
                "t_s": now,
                "axes": axes,
                "axes_source": source,
                "tare": tare_state(rig),
                "protocol": dict(self._run_info) if self._run_info is not None else None,
                "wrench": self._new_wrench,
                "limits": limits,
                "activity": self.activity,
                "errors_seen": self.errors_seen,
                "frames_sent": self.frames_sent,
                "reset_trace": self._reset_trace,  # the trace's rows before this one are of another clock
                "simulated_time": self._run_rig is not None,
                "protocol_running": self._run_stop is not None,  # the live frame pauses meanwhile
            }
        )
        self._new_wrench = []
        self._reset_trace = False
