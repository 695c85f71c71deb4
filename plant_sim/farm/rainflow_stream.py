r"""Rainflow damage counted as the run goes, in bounded memory (ASTM E1049 as the ``rainflow`` package counts it).

``damage.ReversalRecorder`` reduces the shaft torque to turning points; counting them only at the end of a run keeps
every turning point of every turbine (about 0.6 GiB per 1000 s of a 50-run farm chunk with its twins).
``StreamingDamage`` hands the recorder's turning points, every ``flush_ticks`` ticks, to one ``RainflowCounter``
per signal, which keeps only what the count still needs: the stack of ranges not closed yet (the residue, a few
dozen points) and the last two points of the reversal filter. Closed cycles are booked into the damage sums
Σ n S^m at the tick where they close, as ``damage.damage_sums`` books the cycles of a whole sequence.

The counter is the ``rainflow`` package's (3.2) ``reversals`` and ``extract_cycles`` turned into a state machine
that takes points one at a time: the same comparisons in the same order, so the cycles, their order and the sums
equal ``damage_sums`` on the whole sequence bit for bit (``tests/farm/test_damage.py``). That includes the
package's conventions: the first and last points count as reversals, a range holding the starting point is a half
cycle, the residue is counted as half cycles at the end, and a sequence of two points has no cycle.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from plant_sim.farm.damage import GATE_NM, WOHLER_M, ReversalRecorder, book_cycles


class RainflowCounter:
    """Rainflow cycles of one sequence fed in pieces: (range, count, tick at which the cycle closes)."""

    __slots__ = ("_d_last", "_seen", "_stack", "_tick_prev", "_x", "_x_last", "_x_next", "count", "rng", "tick")

    def __init__(self) -> None:
        self._seen = 0  # points fed so far, capped at 3 (only "none", "one", "two" and "more" matter)
        self._x_last = self._x = self._d_last = self._x_next = 0.0
        self._tick_prev = 0
        self._stack: deque[tuple[int, float]] = deque()  # (tick, value) of the reversals not closed yet
        self.rng: list[float] = []
        self.count: list[float] = []
        self.tick: list[int] = []

    def feed(self, ticks: np.ndarray, values: np.ndarray) -> None:
        """The next points of the sequence, in time order."""
        for t, v in zip(ticks.tolist(), values.tolist(), strict=True):
            if self._seen == 0:
                self._x_last, self._seen = v, 1
            elif self._seen == 1:
                self._x, self._d_last, self._seen = v, v - self._x_last, 2
                self._reversal(self._tick_prev, self._x_last)  # the first point is a reversal
            else:
                self._seen = 3
                if v != self._x:
                    d_next = v - self._x
                    if self._d_last * d_next < 0:
                        # the package yields the index before this point, which is the tick fed last
                        self._reversal(self._tick_prev, self._x)
                    self._x_last, self._x, self._d_last = self._x, v, d_next
            self._x_next = v
            self._tick_prev = t

    def finish(self) -> None:
        """The end of the sequence: its last point is a reversal and the residue counts as half cycles."""
        if self._seen == 3:
            self._reversal(self._tick_prev, self._x_next)
        stack = self._stack
        while len(stack) > 1:
            self._cycle(stack[0], stack[1], 0.5)
            stack.popleft()

    def take(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The cycles closed since the last call, as arrays (range, count, tick), and forget them."""
        out = np.array(self.rng), np.array(self.count), np.array(self.tick, dtype=np.int64)
        self.rng, self.count, self.tick = [], [], []
        return out

    def kept(self) -> int:
        """Points held between calls (the residue)."""
        return len(self._stack)

    def _reversal(self, tick: int, x: float) -> None:
        stack = self._stack
        stack.append((tick, x))
        while len(stack) >= 3:
            x1, x2, x3 = stack[-3][1], stack[-2][1], stack[-1][1]
            if abs(x3 - x2) < abs(x2 - x1):
                break
            if len(stack) == 3:  # the range holds the starting point: half a cycle
                self._cycle(stack[0], stack[1], 0.5)
                stack.popleft()
            else:
                self._cycle(stack[-3], stack[-2], 1.0)
                last = stack.pop()
                stack.pop()
                stack.pop()
                stack.append(last)

    def _cycle(self, p1: tuple[int, float], p2: tuple[int, float], count: float) -> None:
        self.rng.append(abs(p1[1] - p2[1]))
        self.count.append(count)
        self.tick.append(p2[0])


class StreamingDamage:
    """Damage sums Σ n S^m (N^m m^m) of n signals sampled every tick, per bin of ``bin_edges`` (ticks).

    ``step(k, x)`` every tick, ``finish(k_end)`` once; then ``sums`` is (n, bins), equal to ``damage_sums`` of each
    signal's whole turning-point sequence. Memory: the recorder's turning points of at most ``flush_ticks`` ticks
    plus each counter's residue.
    """

    def __init__(
        self, n: int, bin_edges: np.ndarray, gate: float = GATE_NM, m: float = WOHLER_M, flush_ticks: int = 6000
    ):
        self.recorder = ReversalRecorder(n, gate)
        self.bin_edges = np.asarray(bin_edges)
        self.m = m
        self.flush_ticks = flush_ticks
        self.counters = [RainflowCounter() for _ in range(n)]
        self.sums = np.zeros((n, len(self.bin_edges) - 1))
        self._next_flush = flush_ticks

    def step(self, k: int, x: np.ndarray) -> None:
        self.recorder.step(k, x)
        if k >= self._next_flush:
            self._flush()
            self._next_flush = k + self.flush_ticks

    def finish(self, k: int) -> None:
        self.recorder.finish(k)
        self._flush()
        for row, counter in enumerate(self.counters):
            counter.finish()
            self._book(row, counter)

    def _flush(self) -> None:
        for row, (ticks, values) in enumerate(self.recorder.drain()):
            if len(ticks):
                self.counters[row].feed(ticks, values)
                self._book(row, self.counters[row])

    def _book(self, row: int, counter: RainflowCounter) -> None:
        rng, count, at = counter.take()
        if len(rng) == 0:
            return
        book_cycles(self.sums[row], self.bin_edges, at, rng, count, self.m)
