"""The part of the console's rig worker that runs a protocol started from the page (cli/console/worker.py).

While it runs: its own rig's axes (on --sim, a simulated rig of its own) and wrench on its own clock, its
run file's name and newest frame for the page; at its end, that rig's axes as it ended, kept to show until
the next command (the event line's lift is that rig's, not the console's). ``tare_state`` says whether the
wrench shown is tared.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from common.wording import status_text

log = logging.getLogger("rig.console")

HISTORY_S = 60.0  # the last minute of the wrench trace


class ProtocolRunning:
    """Mixed into RigWorker: ``_protocol`` and the callbacks of the run it starts."""

    # set by RigWorker.__init__
    _run_stop: Any
    _run_rig: Any
    _run_info: dict | None
    _ended: dict | None
    _axes: dict
    _wrench: Any
    _new_wrench: list
    _reset_trace: bool
    _last_wrench_t: float
    activity: str
    errors_seen: int
    rig: Any
    _sim: Any
    sensor: str
    simulated: bool
    runs_folder: Any
    _on_event: Any

    def _publish_state(self, force: bool = False) -> None:  # RigWorker's
        raise NotImplementedError

    def _protocol(self, command: Any) -> None:  # a worker.Command of kind "protocol"
        from cli.console.protocol_run import StopRequest, library_protocol, run_in_console

        protocol = library_protocol(command.name, self.sensor, self.simulated, list(command.settings))
        origin = command.origin or (0.0, 0.0, 0.0, 0.0)
        stop = StopRequest()
        how = " on simulated time (its own simulated rig, as rig run-protocol --sim)" if self._sim else ""
        self.activity = f"protocol {protocol.name}{how} (STOP ends it)"
        settings = f" with --set {' '.join(command.settings)}" if command.settings else ""
        self._on_event(
            "info", f"{command.who or 'console'}: protocol {protocol.name}{settings} from origin {origin}{how}"
        )
        self._run_info = {"name": protocol.name, "run": "", "frame": -1, "phase": "", "level": 0}
        self._run_stop = stop
        self._publish_state(force=True)
        try:
            out, result = run_in_console(
                self.rig,
                self._sim,
                protocol,
                origin,
                self.runs_folder,
                stop,
                self._protocol_progress,
                on_run_rig=self._show_run_rig,
                on_out=lambda path: self._run_info.update(run=path.name) if self._run_info else None,
            )
        finally:
            self._run_stop = None
            self._run_info = None
        if self._ended is not None:
            self._ended.update(protocol=protocol.name, status=result.status)
        level = {"complete": "info", "interrupted": "warn"}.get(result.status, "error")
        self._on_event(
            level,
            f"protocol {protocol.name}: {status_text(result.status, result.reason)}, {result.frames} frames in "
            f"{out.name}",
        )

    def _show_run_rig(self, run_rig) -> None:
        """A protocol's own rig (--sim) is shown in the live rig's place while it runs: its axes, and
        its wrench on its own (simulated) time, so the trace starts afresh and again at its end. At
        its end, its axes as they ended are kept to show (``_ended``) until the next command: the
        event line's lift is that rig's, not the console's."""
        if run_rig is None and self._run_rig is not None:
            self._publish_state(force=True)  # the run rig's axes as it ended
            self._ended = {"axes": {k: dict(v) for k, v in self._axes.items()}, "protocol": "", "status": ""}
        self._run_rig = run_rig
        self._wrench.clear()
        self._new_wrench = []
        self._reset_trace = True
        self._axes = {}
        self._last_wrench_t = -np.inf

    def _protocol_progress(self, p, run_rig) -> None:
        """Each frame of a protocol running here: its wrench into the trace, the axes to the page.
        Never raises: the page's view must not end a run (the executor's own checks do that)."""
        try:
            if self._run_info is not None:
                self._run_info.update(frame=p.frame - 1, phase=p.phase, level=p.level)
            row = [run_rig.clock.now(), *(float(v) for v in p.wrench)]
            self._wrench.append(row)
            self._new_wrench.append(row)
            while self._wrench and self._wrench[0][0] < row[0] - HISTORY_S:
                self._wrench.popleft()
            self._publish_state(force=True)
        except Exception:
            self.errors_seen += 1
            log.exception("console: showing the progress of a protocol failed")


def tare_state(rig) -> dict:
    """Whether the wrench shown is tared: the gauge's bias (zero until `zero gauge` or a protocol tares it)."""
    bias = getattr(rig.gauge, "bias", None) if rig.gauge is not None else None
    if bias is None:
        return {"tared": False, "text": "no gauge" if rig.gauge is None else "tare unknown"}
    tared = bool(np.any(np.asarray(bias) != 0))
    return {
        "tared": tared,
        "text": "tared" if tared else "untared: raw gauge reading (zero gauge to tare)",
        "bias": [float(v) for v in bias],
    }
