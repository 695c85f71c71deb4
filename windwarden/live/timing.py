"""Deadline-based pacing and loop-latency statistics of the plant's real-time loop.

Tick k of a realtime run at speed-up ×s has the deadline t₀ + (k+1)·dt/s: the time tick k+1 is due to start.
A tick whose work finishes after its deadline is an *overrun*; the loop then starts the next tick at once, so a
late tick is caught up rather than dropped. If the loop falls more than ``resync_s`` behind (a stop of the
process, a swapped-out machine) the schedule is re-anchored to now and the jump is counted as a *resync*.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass
class Pacer:
    """Paces ticks of ``dt`` simulated seconds at ``speed`` × real time against absolute deadlines."""

    dt: float
    speed: float = 1.0
    resync_s: float = 0.5
    clock: Callable[[], float] = time.perf_counter
    sleep: Callable[[float], None] = time.sleep

    def __post_init__(self) -> None:
        self.period = self.dt / self.speed
        self.t0 = self.clock()
        self.k0 = 0
        self.ticks = 0
        self.overruns = 0
        self.resyncs = 0
        self.worst_late_s = 0.0

    def start(self, k: int = 0) -> None:
        """Anchor the schedule: tick ``k`` starts now."""
        self.t0 = self.clock()
        self.k0 = k

    def deadline(self, k: int) -> float:
        return self.t0 + (k + 1 - self.k0) * self.period

    def end_tick(self, k: int) -> bool:
        """Call when tick k's work is done: counts an overrun or sleeps until the deadline. True if overrun."""
        self.ticks += 1
        deadline = self.deadline(k)
        now = self.clock()
        late = now - deadline
        if late > 0.0:
            self.overruns += 1
            self.worst_late_s = max(self.worst_late_s, late)
            if late > self.resync_s:
                self.resyncs += 1
                self.start(k + 1)
            return True
        self.sleep(-late)
        return False

    @property
    def overrun_pct(self) -> float:
        return 100.0 * self.overruns / self.ticks if self.ticks else 0.0


class LatencyStats:
    """Sensor→refs round-trip times, one per tick that got its refs.

    ``summary()`` over the whole run reads a 10 µs histogram (constant time, so a one-hour run's status stays
    cheap on the real-time thread); ``summary(exact=True)`` and ``summary(recent=n)`` compute exact percentiles.
    """

    BIN_S = 1e-5  # s, histogram resolution
    BINS = 20_000  # up to 200 ms; slower round trips land in the last bin

    def __init__(self, capacity: int = 4096):
        self._data = np.empty(capacity)
        self._hist = np.zeros(self.BINS, dtype=np.int64)
        self.n = 0
        self.max = 0.0

    def add(self, seconds: float) -> None:
        if self.n == len(self._data):
            self._data = np.resize(self._data, 2 * len(self._data))
        self._data[self.n] = seconds
        self.n += 1
        self._hist[min(int(seconds / self.BIN_S), self.BINS - 1)] += 1
        self.max = max(self.max, seconds)

    def values(self) -> np.ndarray:
        return self._data[: self.n]

    def _from_histogram(self, q: float) -> float:
        rank = q / 100.0 * (self.n - 1)
        index = int(np.searchsorted(np.cumsum(self._hist), rank, side="right"))
        return (index + 0.5) * self.BIN_S

    def summary(self, recent: int | None = None, exact: bool = False) -> dict[str, float | int | None]:
        """p50, p99 and max in ms (over the last ``recent`` samples if given), and the count."""
        if self.n == 0:
            return {"count": 0, "p50_ms": None, "p99_ms": None, "max_ms": None}
        if recent is None and not exact:
            p50, p99 = self._from_histogram(50.0), self._from_histogram(99.0)
            return {"count": self.n, "p50_ms": 1e3 * p50, "p99_ms": 1e3 * p99, "max_ms": 1e3 * self.max}
        v = self.values() if recent is None else self.values()[-recent:]
        p50, p99 = np.percentile(v, [50.0, 99.0])
        return {
            "count": len(v),
            "p50_ms": 1e3 * float(p50),
            "p99_ms": 1e3 * float(p99),
            "max_ms": 1e3 * float(v.max()),
        }
