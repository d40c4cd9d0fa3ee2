"""Run a protocol plan on a rig with synchronised 1 Hz capture into a run file.

One executor for hardware and the simulated rig. Steps start at their planned times
and captures happen on the fixed grid t = k / rate of protocol time, on the rig's
clock, while moving: the frame count is the plan's, never what idle detection made
of it. Each capture: trigger the camera, take the first frame at or after the
trigger (its timestamp is the capture time), the gauge stream interpolated at that
timestamp (the skew is recorded), the commanded and measured pose. The whole run is
one motion session (rig/motion.py): force limits armed throughout; any exception,
Ctrl-C, SIGTERM or SIGHUP stops all axes, lifts z clear, records why in the file and
closes it.
"""
# Over 400 lines (443): Acquisition is one run's lifecycle (start or resume, capture loop, gauge stream, stop record)
# around one motion session; what it checks before moving is already apart (acquisition/preflight.py).

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from acquisition import schema as S
from acquisition.preflight import (  # noqa: F401 (ProtocolRefused, disk_bytes, preflight: moved to acquisition/preflight.py)
    ProtocolRefused,
    check_against_rig,
    disk_bytes,
    preflight,
    protocol_limits,
)
from acquisition.resume_plan import Restart, superseder
from acquisition.run_file import RunFileError, RunHeader, RunWriter
from protocols.plan import AXES, PHASES, Plan
from rig.errors import DeviceError, ForceLimitExceeded, RigError
from rig.interruption import describe
from rig.types import MotionSession

log = logging.getLogger("acquisition")


@dataclass
class Progress:
    frame: int
    frames: int
    phase: str
    level: int
    t_protocol_s: float
    duration_s: float
    wrench: np.ndarray
    skew_s: float


@dataclass
class RunResult:
    status: str  # complete | aborted | interrupted
    reason: str
    frames: int
    path: Path
    skews_s: list[float] = field(default_factory=list)
    trigger_lag_s: list[float] = field(default_factory=list)
    solver_warnings: int = 0  # simulated rig: contact solves short of tolerance during this run


class Acquisition:
    def __init__(
        self,
        rig,
        plan: Plan,
        *,
        origin: dict[str, float] | None = None,
        monitor_interval_s: float | None = None,
        progress: Callable[[Progress], None] | None = None,
        solver_warnings: Callable[[], int] | None = None,
    ):
        if rig.camera is None or rig.gauge is None:
            raise RigError("acquisition needs the camera and the force gauge open")
        self.rig = rig
        self.plan = plan
        self.clock = rig.clock
        self.origin = {a: 0.0 for a in AXES} | (origin or {})
        self.monitor_interval_s = monitor_interval_s or rig.config.safety.poll_s
        self.progress = progress
        self.protocol = plan.protocol
        self._measured: dict[str, float] = {}
        self._session: MotionSession | None = None  # the motion session while a run is under way
        # simulated rig: the count of contact solves short of tolerance, recorded in the file
        self.solver_warnings = solver_warnings

    @property
    def m(self) -> MotionSession:
        """The open motion session: every move of a run goes through it."""
        if self._session is None:
            raise RigError("no motion session is open: moves happen only inside Acquisition.run")
        return self._session

    # -- helpers ------------------------------------------------------------------
    def _abs(self, rel: tuple[float, ...]) -> dict[str, float]:
        return {a: self.origin[a] + v for a, v in zip(AXES, rel) if a in self.rig.axes}

    def _safe_z(self) -> float:
        return self.origin["z"] + self.protocol.approach_mm

    def _go_to_start(self, pose_rel: tuple[float, ...]) -> None:
        """Lift z clear (if low), move x, y, θ, then come down to the approach height."""
        speed = self.protocol.approach_speed_mm_s
        z_now = self.rig.axes["z"].position()
        if z_now < self._safe_z() - 1e-6:
            self.m.move({"z": self._safe_z()}, speed)
        target = self._abs(pose_rel)
        lateral = {a: v for a, v in target.items() if a != "z"}
        if lateral:  # positioning, not captured: each axis at its configured jog speed
            self.m.move(lateral)
        self.m.move({"z": self._safe_z()}, speed)

    def _capture_frame(self, trigger_t: float, *, triggered: bool = False):
        """The first frame at or after ``trigger_t``; ``triggered``: the camera was already
        asked for it (the capture loop triggers before the safety check: a triggered frame
        is of the capture instant, and on its way while the rig is checked)."""
        cam = self.rig.camera
        if not triggered:
            cam.trigger()
        while True:
            frame = cam.read(timeout_s=5.0)
            if frame.t_s >= trigger_t - 1e-9:
                return frame

    # -- the gauge's full-rate stream (docs/run-file.md, wrench_stream) ----------------
    def _stream_start(self, writer: RunWriter | None) -> None:
        """Record the gauge's samples from the tare on; after a resume, only later than the file's last."""
        self._stream_t, self._stream_same_t = self.clock.now(), 0  # newest sample taken, and how many at that time
        self._stream_floor = writer.last_stream_t_s if writer is not None else None
        self._stream_rows: list[list[float]] = []

    def _collect_stream(self) -> None:
        """Move the samples that arrived since the last call into ``_stream_rows``, tared,
        stamped on the rig clock plus the resume offset (as t_frame_s)."""
        buffer = getattr(self.rig.gauge, "buffer", None)  # a gauge without a stream buffer records none
        if buffer is None:
            return
        # Samples of one read share its arrival stamp, and another read may arrive at the
        # same instant: take those at the last stamp that were not taken yet, then later ones.
        samples = buffer.since(math.nextafter(self._stream_t, -math.inf))[self._stream_same_t :]
        if not samples:
            return
        last = samples[-1].t_s
        same = sum(1 for s in samples if s.t_s == last)
        self._stream_same_t = same + (self._stream_same_t if last == self._stream_t else 0)
        self._stream_t = last
        bias = self.rig.gauge.bias
        for s in samples:
            t = s.t_s + self._t_offset_s
            if self._stream_floor is None or t > self._stream_floor:
                self._stream_rows.append([t, *(s.as_array() - bias)])

    def _measured_pose(self, moving: set[str]) -> list[float]:
        now = self.clock.now()
        for axis in self.rig.axes:
            seen = self.rig.last_status.get(axis)
            # the monitor read it at this very instant, or saw it idle since its last move
            if seen is not None and (seen[0] == now or (axis not in moving and not seen[1].busy)):
                self._measured[axis] = seen[1].position
            elif axis in moving or axis not in self._measured:
                self._measured[axis] = self.rig.axes[axis].position()
        return [self._measured.get(a, self.origin[a]) - self.origin[a] for a in AXES]

    # -- the run ----------------------------------------------------------------------
    def run(self, path: str | Path, *, resume: bool = False, header: dict | None = None) -> RunResult:
        """Run the plan into ``path``, guarded by the protocol's [limits] where it declares them."""
        limits = protocol_limits(self.rig.config, self.protocol)
        if limits is None:
            return self._run(path, resume=resume, header=header)
        with self.rig.narrowed_limits(limits):
            return self._run(path, resume=resume, header=header)

    def _run(self, path: str | Path, *, resume: bool, header: dict | None) -> RunResult:
        path = Path(path)
        plan, proto = self.plan, self.protocol
        hint = (self.origin["z"], "the protocol's origin (--origin)")
        self.monitor_interval_s = check_against_rig(self.rig, plan, self.origin, self.monitor_interval_s)
        writer: RunWriter | None = None
        lock = None if resume else RunWriter.claim(path)  # a second writer is refused before anything moves
        k0 = 0
        self._t_offset_s = 0.0
        self._restart: Restart | None = None
        if resume:
            # back to the start of the level the interruption broke (acquisition/resume_plan.py): its
            # frames move to superseded/, the same protocol checked before anything in the file changes
            found: dict = {}
            writer = RunWriter.reopen(path, superseder(plan, path, _same_protocol, found, _stop_reason(path)))
            self._restart = found.get("restart")
            last = [t for t in (writer.last_t_frame_s, writer.last_stream_t_s) if t is not None]
            if last:  # this process's clock starts anew: time goes on after all the file holds (docs/run-file.md)
                self._t_offset_s = max(last) + 1.0 / proto.capture_hz - self.clock.now()
            done = writer.capture_indices
            k0 = int(done[-1]) + 1 if len(done) else 0
            if self._restart is not None and self._restart.retaken:
                log.warning(
                    "%s: level %d is taken again from capture %d (%d frame(s) moved to %s/retake-%d)",
                    path,
                    self._restart.level,
                    self._restart.k,
                    self._restart.retaken,
                    S.SUPERSEDED,
                    writer.retake,
                )
            if k0 >= plan.frame_count:
                writer.set_status("complete", "")
                writer.close()
                return RunResult("complete", "already complete", int(len(done)), path)
        result = RunResult("running", "", writer.n if writer else 0, path)
        warnings_before = self.solver_warnings() if self.solver_warnings is not None else 0
        # One motion session for the whole run: any error, Ctrl-C, SIGTERM or SIGHUP stops
        # every axis and lifts z to the approach height; _record_stop puts why into `result`.
        motion = self.rig.motion(
            "protocol",
            retract_to_z=self._safe_z(),
            on_stop=lambda report: self._record_stop(result, report),
            on_note=lambda text: log.warning("%s", text),
            surface_hint=hint,
        )
        try:
            with motion as self._session:
                start_pose = plan.steps[0].start
                if k0:  # a resume starts over at the interrupted level's first step (resume_plan.py)
                    start_pose = self._restart.step.start if self._restart else plan.pose_at(plan.capture_time(k0))
                self._go_to_start((start_pose[0], start_pose[1], proto.approach_mm, start_pose[3]))
                self.rig.tare(50)
                self._stream_start(writer)
                reference = self._capture_frame(self.clock.now()).image
                if writer is None:
                    from objects.object_file import load_object, object_file_of

                    info = dict(header or {})
                    mm_per_px = float(info.get("mm_per_px", float("nan")))
                    obj = load_object(proto.object)  # an object file's image is its photo at the frame's scale
                    source = object_file_of(obj)
                    object_image = obj.object_image(
                        reference.shape[1], mm_per_px if math.isfinite(mm_per_px) else 14.0 / reference.shape[1]
                    )
                    writer = RunWriter.create(
                        path,
                        RunHeader(
                            protocol_name=proto.name,
                            protocol_toml=proto.text,
                            rig_config=info.get("rig_config", ""),
                            object_name=obj.name,
                            object_geometry=obj.description,
                            sensor_kind=proto.sensor,
                            mm_per_px=mm_per_px,
                            capture_hz=proto.capture_hz,
                            frames_planned=plan.frame_count,
                            contact_origin=(self.origin["x"], self.origin["y"], self.origin["z"], self.origin["theta"]),
                            phases=PHASES,
                            sensor_profile=str(info.get("sensor_profile", "")),
                            object_file_toml=source.text if source else "",
                            object_photo_sha256=source.photo_sha256 if source else "",
                        ),
                        reference.shape,
                        object_image,
                        reference,
                        lock=lock,
                        codec=info.get("frame_codec") or None,  # None: the image codec where it applies
                    )
                self._main(writer, k0, result)
                self.m.move({"z": self._safe_z()}, proto.approach_speed_mm_s)  # retract, not captured
        except RunFileError:
            raise
        except (RigError, KeyboardInterrupt) as exc:
            # An abort or an interruption: stopped, lifted, and said in `result` and the file
            # (by _record_stop, or here when the session refused to open and nothing moved).
            if result.status == "running":
                result.status, result.reason = describe(exc)
        finally:
            if writer is None and lock is not None:
                lock.release()
            if writer is not None:
                result.frames = writer.n
                try:
                    if self.solver_warnings is not None:
                        result.solver_warnings = self.solver_warnings() - warnings_before
                        writer.set_sim_solver_warnings(result.solver_warnings)
                    writer.set_status(
                        result.status if result.status != "running" else "aborted",
                        result.reason or ("" if result.status == "complete" else "stopped by an error"),
                    )
                finally:
                    writer.close()
        return result

    def _record_stop(self, result: RunResult, report) -> None:
        """How the motion session ended, in the words the run file keeps. Errors that are
        not the rig's own (a driver's ValueError, an OSError) are recorded with their type
        and still propagate: they are bugs or broken machines, not a run's outcome."""
        exc = report.error
        if exc is None:
            status, reason = "complete", ""
        elif isinstance(exc, ForceLimitExceeded):
            status, reason = "aborted", f"force limit: {exc}"
        elif isinstance(exc, DeviceError):
            status, reason = "aborted", f"device error: {exc}"
        elif isinstance(exc, KeyboardInterrupt):
            status, reason = "interrupted", f"{report.reason}; resume with --resume"
        else:
            status, reason = report.status, report.reason
        for problem in report.cleanup_errors:
            reason += f"; {problem}"
            log.error("after %s: %s", status, problem)
        if exc is not None and report.actions:
            reason += "; " + "; ".join(report.actions)
        result.status, result.reason = status, reason

    def _main(self, writer: RunWriter, k0: int, result: RunResult) -> None:
        plan, proto, rig, clock, m = self.plan, self.protocol, self.rig, self.clock, self.m
        steps = plan.captured_steps
        starts, t = [], 0.0
        for step in steps:
            starts.append(t)
            t += step.duration_s
        n_frames = plan.frame_count
        t_k0 = plan.capture_time(k0)
        current, into = plan.locate(t_k0)
        if k0 and self._restart is not None:  # the interrupted level from its first step, at its start
            current, t_k0 = self._restart.step, self._restart.t_s
        i_step = steps.index(current)
        if k0 == 0:
            # the approach is vertical: z alone, so that it runs fast to the gel and slows for the last part
            m.move({"z": self._abs(plan.steps[0].end)["z"]}, plan.steps[0].speeds.get("z", proto.approach_speed_mm_s))
        else:  # back to the gel, then pressed along the protocol's vertical path to where the level starts
            here = current.start if self._restart is not None else current.pose_at(into)
            m.move({"z": self.origin["z"]}, proto.approach_speed_mm_s)
            m.move(
                self._abs(here),
                {a: max(proto.speed_mm_s, 1e-3) if a != "theta" else proto.twist_speed_deg_s for a in self._abs(here)},
            )
        t0 = clock.now() - t_k0  # rig-clock time of protocol time 0
        guard = rig.guard
        moving: set[str] = set()

        def start_step(i: int) -> None:
            nonlocal guard, moving
            step = steps[i]
            targets = {a: v for a, v in self._abs(step.end).items() if a in step.speeds}
            if targets:
                guard = m.start_move(
                    targets, {a: step.speeds[a] for a in targets}, poll_s=self.monitor_interval_s, clamp=False
                )
                moving |= set(targets)

        start_step(i_step)
        next_step = i_step + 1
        k = k0
        next_monitor = clock.now()
        while k < n_frames:
            t_capture = t0 + plan.capture_time(k)
            t_step = t0 + starts[next_step] if next_step < len(steps) else math.inf
            now = clock.now()
            wake = min(t_capture, t_step, next_monitor)
            if wake > now:
                clock.sleep(wake - now)
            now = clock.now()
            if now >= t_step - 1e-9:
                start_step(next_step)
                next_step += 1
            capturing = now >= t_capture - 1e-9
            if capturing:  # exposed at the capture instant, before the checks below (which may step the clock)
                self.rig.camera.trigger()
            if now >= next_monitor - 1e-9:
                # With nothing moving this is the plain force check under the rig's own limits.
                moving = m.monitor(moving, guard if moving else rig.guard, "protocol")
                self._collect_stream()  # the gauge buffer holds seconds: empty it between captures
                next_monitor = now + self.monitor_interval_s
            if capturing:
                self._capture(writer, k, t_capture, moving, result)
                k += 1
        # The last step finishes under its guard, and the wrench after it has to pass too.
        m.settle(moving, guard)

    def _capture(self, writer: RunWriter, k: int, t_trigger: float, moving: set[str], result: RunResult) -> None:
        t_prot = self.plan.capture_time(k)
        frame = self._capture_frame(t_trigger, triggered=True)
        wrench, skew = self.rig.gauge.sample_at(frame.t_s)
        step, _ = self.plan.locate(t_prot)
        self._collect_stream()
        stream, self._stream_rows = self._stream_rows, []
        writer.append(
            frame.image,
            stream=np.array(stream).reshape(-1, 7) if writer.records_stream else None,
            **{
                S.WRENCH: wrench,
                S.POSE_COMMANDED: np.asarray(self.plan.pose_at(t_prot)),
                S.POSE_MEASURED: np.asarray(self._measured_pose(moving)),
                S.T_FRAME: frame.t_s + self._t_offset_s,
                S.T_CAPTURE: t_prot,
                S.WRENCH_SKEW: skew,
                S.CAPTURE_INDEX: k,
                S.STEP_INDEX: step.index,
                S.PHASE_INDEX: writer.phase_index(step.phase),  # the file's own list: a resumed file keeps its order
                S.LEVEL: step.level,
                # recorded again by this resume (its level re-done): which resume; 0 for a first take
                S.RETAKE: writer.retake if self._restart is not None and k < self._restart.k_before else 0,
            },
        )
        result.skews_s.append(skew)
        result.trigger_lag_s.append(frame.t_s - t_trigger)
        if self.progress is not None:
            self.progress(
                Progress(
                    k + 1,
                    self.plan.frame_count,
                    step.phase,
                    step.level,
                    t_prot,
                    self.plan.captured_duration_s,
                    wrench,
                    skew,
                )
            )


def _stop_reason(path: Path) -> str:
    """How the run at ``path`` stopped, as its file says ("" when it cannot be read: resume refuses it)."""
    from acquisition.run_reader import open_for_reading

    try:
        with open_for_reading(path) as f:
            raw = f[S.STATUS_REASON][()] if S.STATUS_REASON in f else b""
    except (RunFileError, OSError, RuntimeError, KeyError):
        return ""
    return raw.decode("utf-8", "replace") if isinstance(raw, bytes) else str(raw)


def _same_protocol(recorded_text: str, proto, path) -> bool:
    """The run's own protocol text and ``proto`` set the same motion (comments and file aside)."""
    from common.errors import ConfigError
    from protocols.spec import parse_protocol

    try:
        return parse_protocol(recorded_text, f"{path} (its protocol_toml)").same_motion(proto)
    except ConfigError:
        return False
