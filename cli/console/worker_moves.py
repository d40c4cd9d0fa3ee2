"""The part of the console's rig worker that moves the rig (cli/console/worker.py): a jog or a homing in
the guarded motion session (rig/motion.py), as `rig jog` and `rig home` do, monitored poll by poll so that
a stop from the page (or the console closing) stops the move between two safety checks.
"""

from __future__ import annotations

import queue
import threading
from typing import Any

import numpy as np

from rig.errors import DeviceTimeout, RigError


class Moving:
    """Mixed into RigWorker: ``_jog``, ``_home`` and the poll loop that follows a started move."""

    # set by RigWorker.__init__ and its own methods
    rig: Any
    activity: str
    _closing: threading.Event
    _commands: queue.Queue
    _on_event: Any
    _io: Any
    _publish_state: Any

    def _jog(self, command: Any) -> None:  # a worker.Command of kind "jog"
        rig = self.rig
        axis, step = command.axis, command.step
        if axis is None or axis not in rig.axes or step is None or not np.isfinite(step):
            raise RigError(f"jog needs an open axis ({', '.join(rig.axes)}) and a finite step, got {axis!r} {step!r}")
        cfg = rig.config.axes[axis]
        here = rig.axes[axis].position()
        last = rig.last_targets.get(axis)  # as `rig jog`: steps from the last target do not accumulate rounding
        base = last if last is not None and abs(here - last) <= rig.tolerance(axis) else here
        target = base + step
        rig.check_targets({axis: target})  # refused before a session opens: nothing moves
        self.activity = f"{axis} → {target:.4f} {cfg.unit}"
        with rig.motion("console jog", on_note=lambda text: self._on_event("warn", text)) as m:
            guard = m.start_move({axis: target})  # at the speed envelope's pace (a clamp is said as an event)
            deadline = rig.clock.now() + 5.0 + 2.0 * m.time_left_s()
            self._on_event("info", f"{command.who or 'console'}: {axis} moving to {target:.4f} {cfg.unit}")
            stopped = self._follow(m, (axis,), guard, deadline)
        final = rig.axes[axis].position()
        if stopped:
            rig.last_targets.pop(axis, None)
            self._on_event("warn", f"{axis} stopped at {final:.4f} {cfg.unit} ({stopped})")
        else:
            rig.last_targets[axis] = target
            self._on_event("info", f"{axis} = {final:.4f} {cfg.unit}")

    def _follow(self, m, names: tuple[str, ...], guard, deadline: float) -> str:
        """Monitor a started move until it has settled; a stop command (or closing) stops
        it at the next poll. Returns why it was stopped, "" when it ran to its end."""
        stopped = ""
        poll_s = self.rig.config.safety.poll_s
        while True:
            if self._closing.is_set():  # Ctrl-C or a signal to the console: the session stops and lifts z
                raise RigError("the console is closing: motion stopped")
            moving = m.monitor(names, guard, "console jog")
            self._io()
            if not moving and m.settled:
                return stopped
            if self.rig.clock.now() > deadline + m.slowed_s:
                raise DeviceTimeout(", ".join(names), "console jog", None, "motion did not finish in time")
            try:
                command = self._commands.get(timeout=poll_s)
            except queue.Empty:
                continue
            if command is None:
                self._closing.set()
            elif command.kind == "stop":
                if not stopped:
                    m.stop()
                    stopped = f"stop from {command.who or 'the console'}"
            else:
                self._on_event("warn", f"{command.kind} refused: a move is in progress (stop it first)")

    def _home(self, command: Any) -> None:  # a worker.Command of kind "home"
        names = (command.axis,) if command.axis else None
        self.activity = f"homing {command.axis or 'all axes'}"
        self._publish_state(force=True)
        with self.rig.motion("console home", on_note=lambda text: self._on_event("warn", text)) as m:
            m.home_axes(names)  # not interruptible from the page yet: Ctrl-C in the terminal is
        self._on_event("info", f"homed {command.axis or 'all axes'}")
