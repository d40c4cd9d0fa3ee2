"""While anything moves: the load a stop could not prevent, and a gauge that has gone quiet.

The guard's plain check compares the newest reading with the limits. By the time a stop ordered
at the next check has braked the axis to rest, a load that grows keeps growing for the check
period, the gauge's sample period and latency, the stop's latency, half the braking time (a load
growing at k·v grows k·v²/2a while braking from v at a) and the reading's own age.
``check_load_ahead`` trips on the reading plus its rate of change times that time (the rate from
the newest samples of this move, or from two checks of a polled gauge), and stops everything when
the gauge's newest sample is older than a few of its periods: a guard without readings guards
nothing.
"""

from __future__ import annotations

import numpy as np

from rig.envelope import load_rate, predict
from rig.errors import DeviceTimeout, ForceLimitExceeded

STALE_GRACE_S = 0.2  # a gauge quiet for 3 periods + its latency + a check + this, while moving: stopped


def check_load_ahead(rig, wrench, guard, speeds: dict[str, float], poll_s: float, since_s: float, previous) -> None:
    """``speeds``: the moving axes' commanded speeds; ``since_s``: when this move started (older
    samples say nothing of its rate); ``previous``: the last check's (t, values), or None."""
    now = rig.clock.now()
    values = wrench.as_array()
    timing = rig.envelope().timing
    age = max(0.0, now - wrench.t_s - timing.gauge_latency_s)
    stale_s = 3 * max(timing.gauge_period_s, timing.gauge_gap_s) + timing.gauge_latency_s + poll_s + STALE_GRACE_S
    if age > stale_s:
        raise DeviceTimeout(
            getattr(rig.gauge, "label", "gauge"),
            "guard",
            None,
            f"its newest sample is {1000 * age:.0f} ms old while {', '.join(sorted(speeds))} "
            f"move (it sends one every {1000 * timing.gauge_period_s:.0f} ms): all axes stopped",
        )
    lag = age + max(
        timing.reaction_s(name, poll_s) + speed / (2.0 * rig.config.axes[name].stop_decel)
        for name, speed in speeds.items()
    )
    rate = load_rate(getattr(rig.gauge, "buffer", None), getattr(rig.gauge, "bias", np.zeros(6)), now, since_s=since_s)
    if rate is None and previous is not None and previous[0] >= since_s and wrench.t_s > previous[0]:
        rate = (values - previous[1]) / (wrench.t_s - previous[0])  # a polled gauge: two checks
    if rate is None:
        return
    ahead = predict(values, rate, lag, np.asarray(guard.limits, dtype=float))
    if ahead is not None:
        raise ForceLimitExceeded(ahead.component, ahead.value, ahead.limit, ahead.unit, ahead.message(lag))
