"""The rig: the configured axes, gauge and camera.

The rig reads; it moves only through ``rig.motion(...)`` (rig/motion.py), the one
session that arms the force limits, watches the wrench until the motion has settled,
and stops everything on any way out.
"""

from __future__ import annotations

import contextlib
import logging
from typing import TYPE_CHECKING

import numpy as np

from rig.clock import Clock, SystemClock
from rig.config import RigConfig
from rig.contact_state import CLEARANCE_MM
from rig.device_floor import restore_left_behind
from rig.envelope import DepthGuard, Envelope, envelope_change, measure_timing
from rig.errors import DeviceError, RigError, SafetyError
from rig.factory import PortPool, open_axis, open_camera, open_gauge
from rig.ownership import Claim, claim_rig
from rig.rig_state import RigState, age_text
from rig.safety import ForceGuard, check_speed, check_target
from rig.surface_identity import check_power_up
from rig.types import Axis, AxisStatus, Camera, ForceGauge, RigStatus

if TYPE_CHECKING:
    from rig.motion import Motion

log = logging.getLogger("rig")


class Rig:
    def __init__(
        self,
        config: RigConfig,
        clock: Clock,
        *,
        axes: dict[str, Axis],
        gauge: ForceGauge | None = None,
        camera: Camera | None = None,
        pool: PortPool | None = None,
        state: RigState | None = None,
    ):
        self.config = config
        self.clock = clock
        self.axes = axes
        self.gauge = gauge
        self.camera = camera
        self._pool = pool
        self.guard = ForceGuard(config.safety) if config.safety else None
        self.stop_errors: list[Exception] = []
        self.last_targets: dict[str, float] = {}  # last target each axis reached
        self.last_status: dict[str, tuple[float, AxisStatus]] = {}  # (clock time, status) from monitor
        self.motion_session: Motion | None = None  # the open motion session, at most one
        self.claim: Claim | None = None  # the devices this process holds (rig/ownership.py), released by close()
        # the remembered tare and gel surface (rig/rig_state.py); Rig.open reads it before opening anything
        self.state = state if state is not None else RigState.for_config(config)
        self._envelope: Envelope | None = None  # measured on the first move (rig/envelope.py)

    @classmethod
    def open(
        cls,
        config: RigConfig,
        clock: Clock | None = None,
        *,
        axes: tuple[str, ...] | None = None,
        gauge: bool = True,
        camera: bool = False,
        sim=None,
        indenter: str | None = None,
    ) -> "Rig":
        """Open only the devices asked for (``axes=None``: all configured axes), claimed first
        (rig/ownership.py): DeviceBusy naming the holder, and nothing opened, when another
        process holds one of them. With z: the controller limits a killed session left narrowed
        are restored and its power-up checked (rig/device_floor.py, rig/surface_identity.py).
        ``indenter``: the object now mounted (``--object``, a protocol's), None: as remembered."""
        clock = clock or SystemClock()
        names = tuple(config.axes) if axes is None else axes
        for name in names:
            if name not in config.axes:
                raise RigError(
                    f"{config.path}: axis {name!r} is not configured (configured: {', '.join(config.axes) or 'none'})"
                )
        state = RigState.for_config(config)  # a damaged state file: one line, before any device opens
        claim = claim_rig(config, names, gauge=gauge, camera=camera)
        pool = PortPool()
        opened_gauge = opened_camera = None
        opened_axes: dict[str, Axis] = {}
        try:
            with claim.explaining():  # a port locked by a process without a claim: named too
                for name in names:
                    opened_axes[name] = open_axis(config.axes[name], pool)
                if gauge and config.gauge is not None:
                    opened_gauge = open_gauge(config.gauge, clock, pool)
                if camera:
                    if config.camera is None:
                        raise RigError(f"{config.path}: no [camera] section")
                    opened_camera = open_camera(config.camera, clock, sim)
        except BaseException:
            if opened_gauge is not None:
                opened_gauge.close()
            pool.close()
            claim.release()
            raise
        rig = cls(config, clock, axes=opened_axes, gauge=opened_gauge, camera=opened_camera, pool=pool, state=state)
        rig.claim = claim
        try:
            for note in (state.mount(indenter), restore_left_behind(rig), check_power_up(rig)):
                if note:
                    log.warning("%s", note)
        except BaseException:
            rig.close()
            raise
        return rig

    # -- reading ----------------------------------------------------------------
    def positions(self) -> dict[str, float]:
        return {name: axis.position() for name, axis in self.axes.items()}

    def status(self) -> RigStatus:
        return RigStatus(
            axes={n: a.status() for n, a in self.axes.items()},
            wrench=self.gauge.read() if self.gauge is not None else None,
        )

    def tare(self, n_samples: int = 20):
        """Tare the gauge (the caller knows nothing touches it) and remember the unloaded
        reading for later commands: a session that starts pressed judges contact by it."""
        if self.gauge is None:
            raise RigError("no force gauge open")
        bias = self.gauge.tare(n_samples)
        guard = self.depth_guard()
        if guard is not None and "z" in self.axes and self.axes["z"].position() < guard.surface_z + CLEARANCE_MM:
            log.warning(
                "tare taken at z = %.3f mm, not clear of the gel surface at %.3f mm: used now, not remembered",
                self.axes["z"].position(),
                guard.surface_z,
            )
            return bias
        self.state.remember_tare(bias)
        return bias

    def envelope(self) -> Envelope:
        """The speed envelope: the safety config with the gauge period and each axis's
        round trip, measured once (reads only) when first asked for."""
        if self._envelope is None:
            self.require_armed(())
            safety = self.config.safety
            assert self.guard is not None and safety is not None  # require_armed refuses a rig without them
            self._envelope = Envelope(safety, self.config.axes, measure_timing(self), self.guard.limits)
            note = envelope_change(self._envelope, self.state, safety.poll_s, "z" in self.axes)
            if note:
                log.warning("%s", note)
        return self._envelope

    @contextlib.contextmanager
    def narrowed_limits(self, limits: np.ndarray):
        """Guard with ``limits`` (each at most the config's: a protocol's [limits]) while the
        block runs, the speed envelope recomputed for them; the config's limits after it,
        however it ends."""
        assert self.guard is not None
        wanted = np.asarray(limits, dtype=float)
        if wanted.shape != self.guard.limits.shape or not np.all(np.isfinite(wanted)) or np.any(wanted <= 0):
            raise SafetyError(f"force/torque limits {wanted.tolist()}: expected 6 finite numbers > 0")
        if np.any(wanted > self.guard.limits):
            raise SafetyError(
                f"force/torque limits {wanted.tolist()} exceed {self.config.path}'s [safety] "
                f"{self.guard.limits.tolist()}: a run may only narrow them"
            )
        saved_guard, saved_envelope = self.guard, self._envelope
        self.guard = ForceGuard.from_limits(wanted)
        if saved_envelope is not None:
            self._envelope = Envelope(self.config.safety, self.config.axes, saved_envelope.timing, wanted)
        try:
            yield
        finally:
            self.guard, self._envelope = saved_guard, saved_envelope

    def depth_guard(self, surface_hint: tuple[float, str] | None = None) -> DepthGuard | None:
        """The depth guard from the remembered gel surface (else ``surface_hint``: (z, how)),
        None while no surface is known or the config states no gel."""
        safety = self.config.safety
        if safety is None or safety.gel_thickness_mm is None:
            return None
        surface = self.state.surface
        if surface is not None:
            z, how = surface.z_mm, f"{surface.how}, {age_text(surface.t_unix)}"
        elif surface_hint is not None:
            z, how = surface_hint
        else:
            return None
        return DepthGuard(z, how, safety.gel_thickness_mm, safety.max_depth_fraction)

    # -- moving: only through a motion session (rig/motion.py) ---------------------------
    def motion(self, what: str, **options) -> "Motion":
        """The one way to move: ``with rig.motion("jog") as m: m.move(...)``.

        Options: ``on_start``, ``on_stop``, ``retract_to_z`` (see rig.motion.Motion).
        """
        from rig.motion import Motion

        return Motion(self, what, **options)

    def require_armed(self, names) -> None:
        if self.gauge is None or self.guard is None:
            raise SafetyError(
                "refusing to move: no force gauge with limits is armed "
                f"(config {self.config.path} needs [gauge] and [safety])"
            )
        for name in names:
            if name not in self.axes:
                raise RigError(f"axis {name!r} is not open")

    def check_targets(
        self, targets: dict[str, float], speed: float | dict[str, float] | None = None
    ) -> dict[str, float]:
        """Soft-limit and speed checks for a move; returns the per-axis speeds. Moves nothing."""
        self.require_armed(targets)
        speeds = {}
        for name, target in targets.items():
            cfg = self.config.axes[name]
            check_target(cfg, target)
            if isinstance(speed, dict):
                s = speed.get(name, cfg.jog_speed)
            else:
                s = cfg.jog_speed if speed is None else speed
            check_speed(cfg, s)
            speeds[name] = s
        return speeds

    def tolerance(self, name: str) -> float:
        """How far from its target an axis may stop: two native steps, at least 0.1 µm."""
        return max(1e-4, 2 * abs(getattr(self.axes[name], "scale", 0.0)))

    def stop_all(self) -> None:
        """Stop every axis; a failure to stop one is logged and kept, never hidden, and the
        others are still stopped (whatever the failure's type). z first: on a shared line its stop
        is not queued behind the others (its stop latency is the one the speed envelope counts)."""
        for _, axis in sorted(self.axes.items(), key=lambda item: item[0] != "z"):
            try:
                axis.stop()
            except Exception as exc:
                self.stop_errors.append(exc)
                log.error("could not stop %s: %s", getattr(axis, "label", axis), exc)

    # -- lifetime ---------------------------------------------------------------
    def close(self) -> None:
        try:
            if self.camera is not None:
                self.camera.close()
            if self.gauge is not None:
                try:
                    self.gauge.close()
                except DeviceError as exc:
                    log.error("closing the gauge: %s", exc)
            if self._pool is not None:
                self._pool.close()
        finally:
            if self.claim is not None:  # after the devices: the next owner finds them closed
                self.claim.release()

    def __enter__(self) -> "Rig":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
