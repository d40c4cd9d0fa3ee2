"""The speed envelope and the depth guard: how fast and how deep a move may go so that the
force guard can still stop it in time (docs/safety.md, "Speed envelope").

A stop lags the load. When the guard sees a load at its limit, the axis keeps moving for

    T = gauge sample period + gauge latency bound + the check's poll period + the stop's latency

at speed v and then decelerates over v²/(2a). Pressing a contact of stiffness k, the load can
pass the limit L by k·(v·T + v²/(2a)). The envelope caps v so that this stays within
margin·L:

    v_max = a·(√(T² + 2·margin·L/(k·a)) − T)

k is the configured worst case for the zone the move is in (inside the gel; below the depth
floor, where only the window's stiffness is safe to assume; sideways while pressed), raised
when the session measures a stiffer contact. T's parts are measured when the rig first moves:
the gauge's sample period from its arrival stamps, each axis's command round trip; the
device's own reaction to a stop and its deceleration come from the axis config.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.types import WRENCH_COMPONENTS, WRENCH_UNITS

TIMING_SAMPLES = 6  # fresh gauge arrivals waited for when the period is measured (0.6 s of a 10 Hz gauge)
TIMING_WINDOW = 40  # newest distinct arrivals the period is the median gap of (those already buffered count)
EXCHANGES = 5  # round trips timed per axis (and per poll of a polled gauge): their median counts
MIN_SPEED = 1e-4  # unit/s: a cap below this cannot make a move safe in any useful time
# A load-rate estimate fits the newest gauge samples of the last RATE_SPAN_S (at least RATE_WINDOW_SAMPLES
# of them) and needs them to span RATE_MIN_SPAN_S: six samples of a 1 kHz gauge span 5 ms, over which its
# noise alone (±0.03 N) reads ±10-27 N/s, enough to stop a slow press for a load it would never reach.
RATE_WINDOW_SAMPLES = 6
RATE_SPAN_S = 0.05
RATE_MIN_SPAN_S = 0.02


@dataclass(frozen=True)
class Timing:
    """The measured parts of a stop's lag (s)."""

    gauge_period_s: float  # the gauge's sample period: the median gap between its arrivals
    gauge_latency_s: float  # the gauge's measurement-to-arrival bound (config fresh_after_s)
    exchange_s: dict[str, float]  # per axis: the median command round trip
    device_reaction_s: dict[str, float]  # per axis: the controller's reaction to stop (config)
    gauge_gap_s: float = 0.0  # the longest gap seen (90th percentile): when a quiet gauge counts as gone

    def stop_latency_s(self, axis: str) -> float:
        """From the stop command leaving the host to the axis starting to decelerate."""
        return self.exchange_s.get(axis, 0.0) + self.device_reaction_s.get(axis, 0.0)

    def reaction_s(self, axis: str, poll_s: float) -> float:
        """T: from the load passing a limit to the axis starting to decelerate."""
        return self.gauge_period_s + self.gauge_latency_s + poll_s + self.stop_latency_s(axis)


def measure_timing(rig) -> Timing:
    """Measure the gauge's sample period and each axis's command round trip (reads only).

    Robust to a loaded host: the period is the median gap over the newest TIMING_WINDOW arrivals
    (a streamed gauge's samples bunch up behind a stalled reader, which moves a high percentile
    of a few gaps tenfold and the median not at all), the round trips the median of EXCHANGES.
    A host that stalls longer than a check is covered by the bounded commands (rig/bounded.py),
    not by the envelope."""
    clock, gauge = rig.clock, rig.gauge
    buffer = getattr(gauge, "buffer", None)
    if buffer is not None and getattr(gauge, "streaming", False):
        stamps = _distinct_stamps(buffer)
        newest = stamps[-1] if stamps else -math.inf
        for _ in range(4 * TIMING_SAMPLES):
            live = sum(1 for t in stamps if t > newest)
            if len(stamps) > TIMING_SAMPLES and live >= 2:  # enough gaps, and arrivals of now among them
                break
            clock.sleep(0.001)  # past the newest sample: the next fresh one is a new arrival
            gauge.read_fresh()
            stamps = _distinct_stamps(buffer)
        gaps = np.diff(stamps[-TIMING_WINDOW - 1 :])
        period = float(np.median(gaps)) if len(gaps) else 0.0
        worst = float(np.percentile(gaps, 90)) if len(gaps) else 0.0
    else:
        durations = []
        for _ in range(EXCHANGES):
            t0 = clock.now()
            gauge.read()
            durations.append(clock.now() - t0)
        period = float(np.median(durations))
        worst = max(durations)
    exchange = {}
    for name, axis in rig.axes.items():
        durations = []
        for _ in range(EXCHANGES):
            t0 = clock.now()
            axis.status()
            durations.append(clock.now() - t0)
        exchange[name] = float(np.median(durations))
    return Timing(
        gauge_period_s=period,
        gauge_latency_s=float(getattr(gauge, "fresh_after_s", 0.0)),
        exchange_s=exchange,
        device_reaction_s={name: rig.config.axes[name].stop_latency_s for name in rig.axes},
        gauge_gap_s=max(worst, period),
    )


def _distinct_stamps(buffer) -> list[float]:
    return sorted({s.t_s for s in buffer.newest(8 * TIMING_WINDOW)})


def overshoot(speed: float, stiffness: float, reaction_s: float, decel: float) -> float:
    """The load past a limit when a contact of ``stiffness`` is pressed at ``speed``."""
    return stiffness * (speed * reaction_s + speed * speed / (2.0 * decel))


def safe_speed(stiffness: float, allowance: float, reaction_s: float, decel: float) -> float:
    """The largest speed whose ``overshoot`` is ``allowance``."""
    # a·(√(T² + c) − T) with c = 2·allowance/(k·a), written without the cancellation of
    # the difference when c ≪ T² (slow gauges, stiff contacts).
    c = 2.0 * allowance / (stiffness * decel)
    return 2.0 * allowance / stiffness / (math.sqrt(reaction_s * reaction_s + c) + reaction_s)


@dataclass(frozen=True)
class Cap:
    """The fastest safe speed of one axis in one zone, and why."""

    axis: str
    speed: float  # unit/s
    zone: str  # "in the gel", "below the depth floor (the window)", "sideways while pressed"
    stiffness: float  # N/mm or N·mm/deg assumed
    stiffness_source: str  # "configured worst case" or "measured ..."
    limit: float  # the limit it protects (N or N·mm)
    component: str  # Fz, Fx/Fy, Mz
    unit: str
    reaction_s: float
    decel: float
    margin: float  # the overshoot allowed, a fraction of the limit

    def why(self) -> str:
        k_unit, f_unit = ("N·mm/deg", "N·mm") if self.component == "Mz" else ("N/mm", "N")
        return (
            f"({self.zone} a stop takes {self.reaction_s * 1000:.0f} ms plus braking at {self.decel:.4g} "
            f"{self.unit}/s², and at {self.stiffness:.4g} {k_unit} ({self.stiffness_source}) a faster move could "
            f"pass the {self.component} limit {self.limit:.4g} {f_unit} by more than {self.margin:.0%})"
        )


class Envelope:
    """Speed caps per axis and zone from the rig's safety config and measured timing."""

    def __init__(self, safety, axes_cfg: dict, timing: Timing, limits: np.ndarray):
        self.safety = safety
        self.axes_cfg = axes_cfg
        self.timing = timing
        self.limits = np.asarray(limits, dtype=float)
        self.measured_stiffness: float | None = None  # the stiffest dFz/dz a session saw

    def normal_stiffness(self) -> tuple[float, str]:
        k = self.safety.stiffness_N_per_mm
        if self.measured_stiffness is not None and self.measured_stiffness > k:
            return self.measured_stiffness, "measured during this move"
        return k, "configured worst case"

    def _zone(self, axis: str, zone: str) -> tuple[float, str, str, float, str]:
        """(stiffness, its source, the zone in words, the limit, its component) of a move.

        zone: "gel" (z pressing inside the gel, or within the surface's uncertainty above it),
        "unknown" (z going down with the gel's surface not known: it may touch anywhere), "deep"
        (z below the depth floor), "pressed" (a lateral or twist axis while the indenter is pressed)."""
        if axis == "z":
            if zone == "deep":
                k, source = self.safety.window_stiffness_N_per_mm, "stiffness of the window behind the gel"
                return k, source, "below the depth floor", float(self.limits[2]), "Fz"
            k, source = self.normal_stiffness()
            where = "near the gel (its surface is not known)" if zone == "unknown" else "in contact with the gel"
            return k, source, where, float(self.limits[2]), "Fz"
        if axis == "theta":
            k = self.safety.twist_stiffness_Nmm_per_deg
            return k, "configured worst case", "twisting while pressed", float(self.limits[5]), "Mz"
        k = self.safety.shear_stiffness_N_per_mm
        limit = float(min(self.limits[0], self.limits[1]))
        return k, "configured worst case", "sliding while pressed", limit, "Fx/Fy"

    def cap(self, axis: str, zone: str, poll_s: float) -> Cap:
        """The fastest safe speed of ``axis`` in ``zone`` when checked every ``poll_s``."""
        cfg = self.axes_cfg[axis]
        k, source, zone_text, limit, component = self._zone(axis, zone)
        reaction = self.timing.reaction_s(axis, poll_s)
        speed = min(safe_speed(k, self.safety.overshoot_margin * limit, reaction, cfg.stop_decel), cfg.max_speed)
        return Cap(
            axis,
            speed,
            zone_text + ":",
            k,
            source,
            limit,
            component,
            cfg.unit,
            reaction,
            cfg.stop_decel,
            self.safety.overshoot_margin,
        )

    def longest_poll_s(self, axis: str, zone: str, speed: float) -> float:
        """The longest check period at which ``speed`` stays inside the cap (< 0: none)."""
        cfg = self.axes_cfg[axis]
        k, _, _, limit, _ = self._zone(axis, zone)
        reaction = (self.safety.overshoot_margin * limit / k - speed * speed / (2.0 * cfg.stop_decel)) / speed
        return reaction - self.timing.reaction_s(axis, 0.0)

    def note_stiffness(self, k_N_per_mm: float) -> bool:
        """A measured dFz/dz; True when it raised the stiffness the caps assume (1.5× it,
        so that a contact that keeps stiffening is still covered until the next estimate)."""
        k, _ = self.normal_stiffness()
        if k_N_per_mm * 1.2 <= k:
            return False
        self.measured_stiffness = 1.5 * k_N_per_mm
        return True


CHANGE_NOTED = 0.15  # an in-contact speed this much away from the one measured before is said


def envelope_change(envelope: "Envelope", state, poll_s: float, has_z: bool) -> str | None:
    """One line when z's speed in contact differs by more than CHANGE_NOTED from the one this rig
    measured before, saying which part of the timing moved; the new summary is remembered."""
    if not has_z:
        return None
    t = envelope.timing
    now = {
        "z_cap_mm_s": envelope.cap("z", "gel", poll_s).speed,
        "gauge_period_s": t.gauge_period_s,
        "gauge_latency_s": t.gauge_latency_s,
        "z_stop_latency_s": t.stop_latency_s("z"),
    }
    before = state.remember_envelope(now)
    was = before.get("z_cap_mm_s")
    if not was or abs(now["z_cap_mm_s"] / was - 1.0) <= CHANGE_NOTED:
        return None
    parts = [
        f"{label} {1000 * now[key]:.1f} ms (was {1000 * before[key]:.1f})"
        for key, label in (
            ("gauge_period_s", "gauge sample period"),
            ("gauge_latency_s", "gauge latency bound"),
            ("z_stop_latency_s", "z stop latency"),
        )
        if key in before and abs(now[key] - before[key]) > 0.1 * max(before[key], 1e-3)
    ]
    why = "; ".join(parts) or "the safety config changed"
    return f"speed envelope changed: z in contact at most {now['z_cap_mm_s']:.3g} mm/s (was {was:.3g} mm/s): {why}"


@dataclass(frozen=True)
class DepthGuard:
    """No z below ``floor`` (surface − fraction × thickness) without the explicit override."""

    surface_z: float  # axis mm where a load began
    how: str  # how the surface was found
    thickness_mm: float
    fraction: float

    @property
    def floor_z(self) -> float:
        return self.surface_z - self.fraction * self.thickness_mm

    @property
    def window_z(self) -> float:
        return self.surface_z - self.thickness_mm

    def describe(self) -> str:
        return (
            f"the depth guard allows {self.fraction * self.thickness_mm:.2f} mm ({self.fraction:.0%} of the "
            f"{self.thickness_mm:g} mm gel) below the gel surface at z = {self.surface_z:.3f} mm ({self.how}), "
            f"so down to z = {self.floor_z:.3f} mm"
        )


@dataclass(frozen=True)
class Predicted:
    component: str
    value: float  # the predicted load at the end of the stop
    now: float  # the last reading
    rate: float  # its rate of change, unit/s
    limit: float
    unit: str

    def message(self, lag_s: float) -> str:
        return (
            f"{self.component} would reach {self.value:.3f} {self.unit} before a stop takes hold "
            f"(now {self.now:.3f} {self.unit}, rising {abs(self.rate):.3g} {self.unit}/s for {lag_s * 1000:.0f} ms): "
            f"over the limit ±{self.limit:.3f} {self.unit}; all axes stopped"
        )


def load_rate(buffer, bias: np.ndarray, now_s: float, since_s: float = -math.inf) -> np.ndarray | None:
    """d(wrench)/dt (6,) by least squares over the gauge samples stamped after ``since_s`` in the last
    RATE_SPAN_S before the newest (at least RATE_WINDOW_SAMPLES of them); None when they are fewer than
    three, span less than RATE_MIN_SPAN_S (a burst's shared stamps, a move just begun) or the newest is
    over a second old."""
    if buffer is None:
        return None
    n = RATE_WINDOW_SAMPLES
    samples = buffer.newest(n)
    while len(samples) == n and samples[-1].t_s - samples[0].t_s < RATE_SPAN_S and samples[0].t_s > since_s:
        n *= 2  # a fast gauge: more samples to cover the span
        samples = buffer.newest(n)
    if samples:
        cut = max(since_s, samples[-1].t_s - RATE_SPAN_S)
        window = [s for s in samples if s.t_s > cut]
        samples = (
            window
            if len(window) >= RATE_WINDOW_SAMPLES
            else [s for s in samples[-RATE_WINDOW_SAMPLES:] if s.t_s > since_s]
        )
    if len(samples) < 3:
        return None
    t = np.array([s.t_s for s in samples])
    if t[-1] - t[0] < RATE_MIN_SPAN_S or now_s - t[-1] > 1.0:
        return None
    values = np.array([s.as_array() for s in samples]) - bias
    t = t - t.mean()
    return (t @ (values - values.mean(axis=0))) / float(t @ t)


def predict(wrench_values: np.ndarray, rate: np.ndarray, lag_s: float, limits: np.ndarray) -> Predicted | None:
    """The first component whose load, growing at ``rate`` for ``lag_s``, passes its limit."""
    values = np.asarray(wrench_values, dtype=float)
    growing = np.where(np.sign(rate) == np.sign(values), rate, 0.0)  # only a load moving away from zero
    ahead = values + growing * lag_s
    over = np.abs(ahead) > limits
    if not over.any():
        return None
    i = int(np.argmax(np.abs(ahead) / limits))
    return Predicted(
        WRENCH_COMPONENTS[i], float(ahead[i]), float(values[i]), float(rate[i]), float(limits[i]), WRENCH_UNITS[i]
    )
