"""The guard's load rate (rig/envelope.py ``load_rate``) fits the gauge's samples over tens of
milliseconds, not over its newest six: at 1 kHz six samples span 5 ms, and a gauge's noise alone
then reads as a load rising fast enough to stop a slow press that would never reach its limit."""

from __future__ import annotations

import numpy as np
import pytest

from rig.drivers.wrench_stream import WrenchBuffer
from rig.envelope import RATE_MIN_SPAN_S, load_rate
from rig.types import Wrench

NOISE_N = 0.03  # the simulated gauge's: ±0.03 N


def _buffer(rate_hz: float, seconds: float, slope_N_s: float, *, burst: int = 1, seed: int = 0) -> WrenchBuffer:
    """A gauge at ``rate_hz`` whose Fz rises at ``slope_N_s`` with uniform noise; samples read ``burst`` at a
    time share the host's stamp of the last of them (how a stream's reads arrive)."""
    rng = np.random.default_rng(seed)
    buffer = WrenchBuffer()
    n = int(seconds * rate_hz)
    for i in range(n):
        t_true = i / rate_hz
        stamp = (i // burst * burst + burst - 1) / rate_hz
        fz = 2.0 + slope_N_s * t_true + rng.uniform(-NOISE_N, NOISE_N)
        buffer.push(Wrench(stamp, 0.0, 0.0, fz, 0.0, 0.0, 0.0))
    return buffer


def _newest_t(buffer: WrenchBuffer) -> float:
    return buffer.newest(1)[0].t_s


@pytest.mark.parametrize("burst", [1, 6])
def test_a_steady_load_on_a_noisy_1khz_gauge_reads_as_steady(burst):
    """A load that does not change: its rate stays within 2 N/s (six samples read ±10-27 N/s)."""
    worst = 0.0
    for seed in range(20):
        buffer = _buffer(1000.0, 0.5, 0.0, burst=burst, seed=seed)
        rate = load_rate(buffer, np.zeros(6), _newest_t(buffer))
        assert rate is not None
        worst = max(worst, abs(rate[2]))
    assert worst < 2.0, worst


@pytest.mark.parametrize("burst", [1, 6])
def test_a_load_rising_fast_reads_its_rate(burst):
    """A stiff contact pressed quickly (120 N/s: 100 N/mm at 1.2 mm/s) reads within 5 %."""
    buffer = _buffer(1000.0, 0.5, 120.0, burst=burst)
    rate = load_rate(buffer, np.zeros(6), _newest_t(buffer))
    assert rate is not None and rate[2] == pytest.approx(120.0, rel=0.05)


def test_a_slow_gauge_still_gives_a_rate_from_its_newest_samples():
    """10 Hz: the last 50 ms hold one sample; the newest six (0.5 s) give the rate."""
    buffer = _buffer(10.0, 2.0, 3.0)
    rate = load_rate(buffer, np.zeros(6), _newest_t(buffer))
    assert rate is not None and rate[2] == pytest.approx(3.0, abs=0.5)


def test_samples_spanning_too_short_a_time_give_no_rate():
    """Samples of this move spanning under RATE_MIN_SPAN_S (a move just begun, one burst's shared stamp):
    no rate (the guard then compares two checks), never a rate from 5 ms of noise."""
    buffer = _buffer(1000.0, 0.5, 0.0)
    t = _newest_t(buffer)
    assert load_rate(buffer, np.zeros(6), t, since_s=t - 0.006) is None
    assert load_rate(buffer, np.zeros(6), t, since_s=t - RATE_MIN_SPAN_S - 0.003) is not None
    bunched = _buffer(1000.0, 0.5, 0.0, burst=50)
    assert load_rate(bunched, np.zeros(6), _newest_t(bunched), since_s=_newest_t(bunched) - 0.04) is None


def test_an_old_newest_sample_gives_no_rate():
    buffer = _buffer(1000.0, 0.5, 50.0)
    assert load_rate(buffer, np.zeros(6), _newest_t(buffer) + 1.5) is None
