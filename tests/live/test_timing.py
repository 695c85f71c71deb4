"""Deadline pacing and latency statistics, against a fake clock (no sleeping)."""

from __future__ import annotations

import numpy as np
import pytest

from windwarden.live.timing import LatencyStats, Pacer

pytestmark = pytest.mark.in_process  # no network, no process: the parallel phase (tests/conftest.py)


class FakeClock:
    def __init__(self):
        self.now = 100.0
        self.slept: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.slept.append(seconds)
        self.now += seconds


def test_pacer_sleeps_to_absolute_deadlines_and_counts_overruns():
    clock = FakeClock()
    pacer = Pacer(dt=0.01, speed=2.0, clock=clock, sleep=clock.sleep)  # period 5 ms
    pacer.start(0)
    work = [0.001, 0.001, 0.008, 0.001, 0.001]  # tick 2 overruns by 4 ms; tick 3 catches up
    overrun = []
    for k, w in enumerate(work):
        clock.now += w
        overrun.append(pacer.end_tick(k))
    assert overrun == [False, False, True, False, False]
    assert pacer.overruns == 1 and pacer.overrun_pct == pytest.approx(20.0)
    assert clock.now == pytest.approx(100.0 + 5 * 0.005)  # back on the schedule: deadlines are absolute
    assert pacer.worst_late_s == pytest.approx(0.003)


def test_pacer_resyncs_after_a_long_stall():
    clock = FakeClock()
    pacer = Pacer(dt=0.01, speed=1.0, resync_s=0.5, clock=clock, sleep=clock.sleep)
    pacer.start(0)
    clock.now += 2.0  # the process was stopped for 2 s
    assert pacer.end_tick(0)
    assert pacer.resyncs == 1
    clock.now += 0.001
    assert not pacer.end_tick(1)  # the schedule starts again from the stall, no burst of catch-up ticks
    assert clock.now == pytest.approx(100.0 + 2.0 + 0.01)


def test_latency_percentiles_match_numpy():
    rng = np.random.default_rng(0)
    values = rng.exponential(0.002, 10_000)
    stats = LatencyStats(capacity=16)
    for v in values:
        stats.add(float(v))
    summary = stats.summary()
    assert summary["count"] == 10_000
    assert summary["p50_ms"] == pytest.approx(1e3 * np.percentile(values, 50), abs=0.011)
    assert summary["p99_ms"] == pytest.approx(1e3 * np.percentile(values, 99), abs=0.011)  # 10 µs histogram
    exact = stats.summary(exact=True)
    assert exact["p50_ms"] == pytest.approx(1e3 * np.percentile(values, 50))
    assert exact["p99_ms"] == pytest.approx(1e3 * np.percentile(values, 99))
    assert exact["max_ms"] == summary["max_ms"] == pytest.approx(1e3 * values.max())
    assert stats.summary(recent=100)["p50_ms"] == pytest.approx(1e3 * np.percentile(values[-100:], 50))
    assert LatencyStats().summary()["p99_ms"] is None
