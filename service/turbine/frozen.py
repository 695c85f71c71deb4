"""Frozen readings: a signal that repeats its last value exactly for a number of ticks (a stuck sensor)."""

from __future__ import annotations

import numpy as np


class FrozenReadings:
    """Counts identical consecutive readings per column of an (n, m) signal; ``frozen`` where a reading has not
    changed for ``ticks`` ticks (``ticks − 1`` repeats).

    Cheap on the common tick: while no count is running, a tick with no repeated reading changes nothing, and the
    counts are not touched.
    """

    def __init__(self, shape: tuple[int, ...], ticks: int, fast=None):
        self.ticks = ticks
        self._fast = fast  # ``service.turbine.fast`` (``wwcore.backend``) or None: the repeat test compiled
        self.count = np.zeros(shape, dtype=np.int64)
        self.frozen = np.zeros(shape, dtype=bool)
        self.counting = False  # False only while every count is 0
        self._prev: np.ndarray | None = None

    @property
    def previous(self) -> np.ndarray | None:
        """The last readings taken (None before the first)."""
        return self._prev

    def push(self, y: np.ndarray, repeated: bool | None = None) -> bool:
        """Take this tick's readings; True when any reading is frozen now. ``repeated``: whether any reading equals
        ``previous``'s, where the caller has tested it already (a compiled tick); None: tested here."""
        any_frozen = False
        if self._prev is not None:
            quiet = self._fast is not None and not (self.counting or self.ticks < 2)
            if repeated is None and quiet:
                repeated = self._fast.any_equal(y, self._prev)
            if quiet and not repeated:  # the common tick: nothing repeated or counting
                self._prev = y
                return False
            same = y == self._prev
            if self.counting or self.ticks < 2 or same.any():  # else every count is 0 and stays 0
                self.count = (self.count + 1) * same
                self.frozen = self.count >= self.ticks - 1
                self.counting = bool(self.count.any())
                any_frozen = bool(self.frozen.any())
        self._prev = y
        return any_frozen
