"""A library protocol started from the console, run as ``rig run-protocol`` runs it.

The same path as the command line: ``acquisition.executor.Acquisition`` (preflight against the
config's limits, one guarded motion session for the whole run, the run file closed with its
status), the progress sidecar beside the run file (the page's progress panel shows it), the run
file in the console's runs folder. On hardware (or a `rig sim serve` config) the run uses the rig
the console holds. On ``--sim`` it runs as ``rig run-protocol --sim`` does: on its own simulated
rig on discrete-event time (cli/simulated.py), the protocol's object mounted, as fast as its
frames can be made; the console's live simulated rig waits meanwhile.

Stopping it: ``rig run-protocol`` turns SIGINT into ``MotionInterrupted`` raised in the main
thread; the worker is not the main thread, so the run's clock is wrapped in an
``InterruptibleClock`` instead: every wait of the executor and of its motion session goes
through it (in slices of at most ``SLICE_S`` of real time; on discrete-event time a wait is
instant, so each wait is one slice), and after ``StopRequest.request(why)`` the next wait raises
``MotionInterrupted(why)`` once. The session then stops every axis and lifts z, and the file
ends ``interrupted`` with that reason, as after Ctrl-C. It raises only once, so a second STOP
cannot cut the stop sequence's lift short (as a second Ctrl-C cannot).
"""

from __future__ import annotations

import datetime as dt
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from common.errors import ConfigError

SLICE_S = 0.05  # a stop acts within this much of a wait (the executor waits at most a poll)
SIM_INDENTER = "sphere10mm"  # what the console's live simulated rig has mounted
MAX_SETTINGS = 32  # --set values one page request may carry


class StopRequest:
    """STOP for a run (any thread may ask): the run's next wait raises ``MotionInterrupted`` once."""

    def __init__(self):
        self._why: str | None = None
        self._fired = False
        self._lock = threading.Lock()

    def request(self, why: str) -> None:
        with self._lock:
            if self._why is None:
                self._why = why

    @property
    def requested(self) -> str | None:
        return self._why

    def raise_once(self) -> None:
        from rig.interruption import MotionInterrupted

        with self._lock:
            if self._why is None or self._fired:
                return
            self._fired = True
        raise MotionInterrupted(self._why)


class InterruptibleClock:
    """The rig's clock, whose ``sleep`` raises ``MotionInterrupted`` once after a stop was requested."""

    def __init__(self, clock, stop: StopRequest | None = None):
        self._clock = clock
        self.stop = stop or StopRequest()
        self._slice_s = None if hasattr(clock, "add_listener") else SLICE_S  # discrete time: a wait is instant

    def request(self, why: str) -> None:
        """Ask the run to stop (any thread): the next wait raises."""
        self.stop.request(why)

    @property
    def requested(self) -> str | None:
        return self.stop.requested

    def now(self) -> float:
        return self._clock.now()

    def sleep(self, dt_s: float) -> None:
        if self._slice_s is None:
            self.stop.raise_once()
            self._clock.sleep(dt_s)
            return
        remaining = dt_s
        while True:
            self.stop.raise_once()
            if remaining <= 0:
                return
            part = min(remaining, self._slice_s)
            self._clock.sleep(part)
            remaining -= part


def check_origin(values: Any) -> tuple[float, float, float, float]:
    """The page's origin: four finite numbers x, y, z (mm), theta (deg)."""
    import math

    ok = isinstance(values, list) and len(values) == 4
    ok = ok and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values)
    if not ok:
        raise ConfigError("console", "origin", f"{values!r}: expected four finite numbers x, y, z (mm), theta (deg)")
    return (float(values[0]), float(values[1]), float(values[2]), float(values[3]))


def check_settings(values: Any) -> list[str]:
    """The page's ``--set`` values: a list of section.key=value texts (checked further by the
    protocol loader, as the command line's are)."""
    if values is None:
        return []
    ok = isinstance(values, list) and len(values) <= MAX_SETTINGS and all(isinstance(v, str) for v in values)
    if not ok:
        raise ConfigError(
            "console", "settings", f"{values!r}: expected a list of section.key=value texts (at most {MAX_SETTINGS})"
        )
    return [v.strip() for v in values if v.strip()]


def library_protocol(name: Any, sensor: str, simulated: bool, settings: list[str] | None = None):
    """A protocol of the library by name (never a path from the page) with the page's ``--set``
    values, for this console's sensor kind (set as ``--set protocol.sensor=`` would). With the
    live simulated rig the run brings its own simulated rig, so any library object runs."""
    from cli.protocol_cmds import known_protocol
    from protocols.spec import load_protocol, protocol_names

    if not isinstance(name, str) or name not in protocol_names():
        known_protocol(str(name))  # one line: did you mean…
        raise ConfigError("console", "protocol", f"{name!r} is not in the protocol library")
    settings = list(settings or [])
    protocol = load_protocol(name, settings)
    if protocol.sensor != sensor:  # the camera is what it is: the run says so (as --set protocol.sensor=)
        protocol = load_protocol(name, [*settings, f"protocol.sensor={sensor}"])
    del simulated  # any library protocol runs: on --sim on a simulated rig of its own
    return protocol


def plan_summary(protocol, simulated: bool) -> dict:
    """What the page shows before a run starts: the protocol's duration (protocol time), frames
    at its capture rate and the disk it takes, as `rig protocols show` prints them."""
    from cli.protocol_cmds import disk_estimate, fmt_duration
    from protocols.plan import Plan

    plan = Plan.of(protocol)
    raw, written, how = disk_estimate(plan, simulated)
    return {
        "name": protocol.name,
        "object": protocol.object,
        "sensor": protocol.sensor,
        "duration_s": plan.total_duration_s,
        "duration": fmt_duration(plan.total_duration_s),
        "frames": plan.frame_count,
        "capture_hz": protocol.capture_hz,
        "raw_bytes": raw,
        "disk_bytes": written,
        "disk": how,
        "simulated_time": simulated,
    }


def new_run_path(folder: Path, protocol) -> Path:
    from cli.protocol_cmds import check_new_run_path

    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(str(folder), "--runs", f"cannot create it: {exc.strerror}") from None
    out = folder / f"{protocol.name}-{dt.datetime.now().strftime('%Y%m%d-%H%M%S')}.h5"
    check_new_run_path(out)
    return out


def run_in_console(
    rig,
    simulated,
    protocol,
    origin: tuple[float, float, float, float],
    folder: Path,
    stop: StopRequest,
    on_progress: Callable[[Any, Any], object],
    on_run_rig: Callable[[Any], object] = lambda rig: None,
    on_out: Callable[[Path], object] = lambda path: None,
):
    """Run ``protocol`` into a new file in ``folder``; returns (path, RunResult). ``simulated``:
    the console's live simulated rig (--sim), else None (the run uses ``rig``). ``on_progress(p,
    run_rig)`` per frame; ``on_run_rig(rig)`` when a run rig of its own opens, ``(None)`` at its end;
    ``on_out(path)`` once the run file's name is chosen."""
    from acquisition.executor import Acquisition
    from acquisition.schema import RIG_CONFIG_MARK
    from cli.console.run_progress import ProgressWriter
    from protocols.plan import AXES, Plan

    plan = Plan.of(protocol)
    out = new_run_path(folder, protocol)
    on_out(out)

    def run(run_rig, header, **options):
        original = run_rig.clock
        run_rig.clock = InterruptibleClock(original, stop)  # every wait of the run can now be stopped
        try:
            with ProgressWriter(
                out, protocol=protocol.name, frames=plan.frame_count, levels_mm=protocol.levels
            ) as sidecar:

                def progress(p) -> None:
                    sidecar.update(p)
                    on_progress(p, run_rig)

                acquisition = Acquisition(run_rig, plan, origin=dict(zip(AXES, origin)), progress=progress, **options)
                return acquisition.run(out, header=header)
        finally:
            run_rig.clock = original

    if simulated is not None:  # as `rig run-protocol --sim`: its own rig, on simulated time
        from cli.simulated import monitor_interval_s, simulated_rig_for

        with simulated_rig_for(protocol) as (run_rig, sim, header):
            header["rig_config"] = header["rig_config"].replace(
                RIG_CONFIG_MARK, RIG_CONFIG_MARK + "\n# started from rig console --sim", 1
            )
            on_run_rig(run_rig)
            try:
                result = run(
                    run_rig,
                    header,
                    monitor_interval_s=monitor_interval_s(protocol),
                    solver_warnings=lambda: sim.world.contact.solver_warnings,
                )
            finally:
                on_run_rig(None)
        return out, result
    cfg = rig.config
    mm_per_px = cfg.camera.mm_per_px if cfg.camera and cfg.camera.mm_per_px is not None else float("nan")
    return out, run(rig, {"rig_config": Path(cfg.path).read_text(), "mm_per_px": mm_per_px})
