"""A library protocol started from the console, on the rig the console holds.

The same path as ``rig run-protocol``: ``acquisition.executor.Acquisition`` on the worker's
rig (preflight against the config's limits, one guarded motion session for the whole run,
the run file closed with its status), the progress sidecar beside the run file (the page's
progress panel shows it), the run file in the console's runs folder.

Stopping it: ``rig run-protocol`` turns SIGINT into ``MotionInterrupted`` raised in the
main thread; the worker is not the main thread, so the run is given an ``InterruptibleClock``
instead: every wait of the executor and of its motion session goes through it, in slices of
at most ``SLICE_S``, and after ``request(why)`` the next wait raises ``MotionInterrupted(why)``
once. The session then stops every axis and lifts z, and the file ends ``interrupted`` with
that reason, as after Ctrl-C. It raises only once, so a second STOP cannot cut the stop
sequence's lift short (as a second Ctrl-C cannot).
"""

from __future__ import annotations

import datetime as dt
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from common.errors import ConfigError

SLICE_S = 0.05  # a stop acts within this much of a wait (the executor waits at most a poll)
SIM_INDENTER = "sphere10mm"  # what the console's simulated rig has mounted


class InterruptibleClock:
    """The rig's clock, whose ``sleep`` raises ``MotionInterrupted`` once after ``request``."""

    def __init__(self, clock):
        self._clock = clock
        self._why: str | None = None
        self._fired = False
        self._lock = threading.Lock()

    def request(self, why: str) -> None:
        """Ask the run to stop (any thread): the next wait raises."""
        with self._lock:
            if self._why is None:
                self._why = why

    @property
    def requested(self) -> str | None:
        return self._why

    def now(self) -> float:
        return self._clock.now()

    def sleep(self, dt_s: float) -> None:
        remaining = dt_s
        while True:
            self._raise_once()
            if remaining <= 0:
                return
            part = min(remaining, SLICE_S)
            self._clock.sleep(part)
            remaining -= part

    def _raise_once(self) -> None:
        from rig.interruption import MotionInterrupted

        with self._lock:
            if self._why is None or self._fired:
                return
            self._fired = True
        raise MotionInterrupted(self._why)


def check_origin(values: Any) -> tuple[float, float, float, float]:
    """The page's origin: four finite numbers x, y, z (mm), theta (deg)."""
    import math

    ok = isinstance(values, list) and len(values) == 4
    ok = ok and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values)
    if not ok:
        raise ConfigError("console", "origin", f"{values!r}: expected four finite numbers x, y, z (mm), theta (deg)")
    return (float(values[0]), float(values[1]), float(values[2]), float(values[3]))


def library_protocol(name: Any, sensor: str, simulated: bool):
    """A protocol of the library by name (never a path from the page), for this console's sensor
    kind (set as ``--set protocol.sensor=`` would); with the simulated rig, for its indenter."""
    from protocols.spec import load_protocol, protocol_names

    names = protocol_names()
    if not isinstance(name, str) or name not in names:
        raise ConfigError("console", "protocol", f"{name!r} is not in the protocol library ({', '.join(names)})")
    protocol = load_protocol(name)
    if protocol.sensor != sensor:  # the camera is what it is: the run says so (as --set protocol.sensor=)
        protocol = load_protocol(name, [f"protocol.sensor={sensor}"])
    if simulated and protocol.object != SIM_INDENTER:
        raise ConfigError(
            f"protocol {name}",
            "protocol.object",
            f"is {protocol.object}; the console's simulated rig has {SIM_INDENTER} mounted "
            f"(for other objects: rig run-protocol {name} --sim)",
        )
    return protocol


def run_in_console(
    rig,
    simulated,
    protocol,
    origin: tuple[float, float, float, float],
    folder: Path,
    clock: InterruptibleClock,
    on_progress: Callable[[Any], object],
):
    """Run ``protocol`` on ``rig`` into a new file in ``folder``; returns (path, RunResult)."""
    from acquisition.executor import Acquisition
    from acquisition.schema import FAST_CODEC, RIG_CONFIG_MARK
    from cli.console.run_progress import ProgressWriter
    from cli.protocol_cmds import check_new_run_path
    from protocols.plan import AXES, Plan

    plan = Plan.of(protocol)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(str(folder), "--runs", f"cannot create it: {exc.strerror}") from None
    out = folder / f"{protocol.name}-{dt.datetime.now().strftime('%Y%m%d-%H%M%S')}.h5"
    check_new_run_path(out)
    cfg = rig.config
    mm_per_px = cfg.camera.mm_per_px if cfg.camera and cfg.camera.mm_per_px is not None else float("nan")
    if simulated is not None:
        rig_config = RIG_CONFIG_MARK + "\n# started from rig console --sim\n" + simulated.config_toml()
    else:
        rig_config = Path(cfg.path).read_text()
    header = {"rig_config": rig_config, "mm_per_px": mm_per_px}
    if simulated is not None:  # the simulated camera's frames: the fast codec, as `rig run-protocol --sim`
        header["frame_codec"] = FAST_CODEC

    def progress(p) -> None:
        sidecar.update(p)
        on_progress(p)

    original = rig.clock
    rig.clock = clock  # every wait of the run (executor and motion session) can now be stopped
    try:
        with ProgressWriter(out, protocol=protocol.name, frames=plan.frame_count, levels_mm=protocol.levels) as sidecar:
            acquisition = Acquisition(rig, plan, origin=dict(zip(AXES, origin)), progress=progress)
            result = acquisition.run(out, header=header)
    finally:
        rig.clock = original
    return out, result
