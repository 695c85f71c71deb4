"""Frozen readings: a signal that repeats its last value exactly for a number of ticks (a stuck sensor)."""

from __future__ import annotations

import numpy as np


class FrozenReadings:
    """Counts identical consecutive readings per column of an (n, m) signal; ``frozen`` where a reading has not
    changed for ``ticks`` ticks (``ticks − 1`` repeats).

    Cheap on the common tick: while no count is running, a tick with no repeated reading changes nothing, and the
    counts are not touched.
    """

    def __init__(self, shape: tuple[int, ...], ticks: int):
        self.ticks = ticks
        self.count = np.zeros(shape, dtype=np.int64)
        self.frozen = np.zeros(shape, dtype=bool)
        self.counting = False  # False only while every count is 0
        self._prev: np.ndarray | None = None

    def push(self, y: np.ndarray) -> bool:
        """Take this tick's readings; True when any reading is frozen now."""
        any_frozen = False
        if self._prev is not None:
            same = y == self._prev
            if self.counting or self.ticks < 2 or same.any():  # else every count is 0 and stays 0
                self.count = (self.count + 1) * same
                self.frozen = self.count >= self.ticks - 1
                self.counting = bool(self.count.any())
                any_frozen = bool(self.frozen.any())
        self._prev = y
        return any_frozen
