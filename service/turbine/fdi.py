"""Speed-sensor fault detection and isolation from the observer bank's residuals (seed 000, Section 3).

In the manner of Odgaard & Stoustrup (2010): each observer's residual is decoupled from the unknown input, so
it stays at its noise level unless a sensor it uses is faulty. The decision logic is a generalised observer
scheme on the bank:

* **Consistency.** Observer j is consistent at tick n when χ²_j = ‖W_j r_j‖² ≤ h_j, the whitened residual's
  χ² statistic with rank_j degrees of freedom (W_j from the closed-form residual covariance S_j, ``uio``).
* **Detection and isolation.** While the selected observer (the one that leaves out the flagged sensors) is
  consistent, nothing changes. When it is not, the supervisor searches the whole bank and selects the
  consistent observer that leaves out the fewest sensors (ties: smallest χ²_j/h_j); the sensors it leaves out
  are the isolated faults. Searching the whole bank, not only observers that leave out more, lets a wrong
  early isolation (a small fault masked by noise at its first tick) correct itself at the next inconsistency.
* **Fault end.** A flagged sensor is cleared when the observer that uses it again (selected set plus that
  sensor) has been consistent at the looser clearing threshold for ``clear_ticks`` consecutive ticks.
* **Frozen signals.** A reading that does not change at all for ``frozen_ticks`` ticks is flagged at once
  (fixed-value and stuck faults carry no noise; this also catches a fixed value that happens to equal the
  truth, which no residual can see).

Thresholds come from the false-alarm budget (PARAMETERS.md d), not from fault data: detection uses
h_j = χ²⁻¹_{rank_j}(1 − α), α = rate·Ts/1000 for a design rate of false alarms per 1000 s (default 0.1, the
requirement being 1); clearing uses α_clear (default 1 %) so a healthy sensor passes ``clear_ticks`` ticks in
a row with probability (1 − α_clear)^clear_ticks ≈ 95 %.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from service.turbine.bank import BankDesign
from wwcore.channels import SPEED_SENSORS

N_SPEED = len(SPEED_SENSORS)
_BITS = 1 << np.arange(N_SPEED)


@dataclass(frozen=True)
class FDISettings:
    false_alarms_per_1000s: float = 0.1  # design rate of the detection test (requirement: < 1)
    clear_alpha: float = 0.01  # per-tick false-rejection probability of the clearing test
    clear_ticks: int = 5  # consecutive consistent ticks before a sensor is cleared
    frozen_ticks: int = 3  # identical consecutive readings that mark a sensor frozen
    warmup_s: float = 5.0  # no decisions while the observers converge from their initial state


def _mask(left_out: frozenset[str]) -> int:
    return sum(1 << SPEED_SENSORS.index(s) for s in left_out)


class SpeedSensorFDI:
    """Flags faulty speed sensors for n turbines; ``faulty`` (n, 4) bool in SPEED_SENSORS order."""

    def __init__(self, bank: BankDesign, n: int, dt: float, settings: FDISettings = FDISettings()):
        self.bank = bank
        self.s = settings
        self.n = n
        alpha = settings.false_alarms_per_1000s * dt / 1000.0
        self.h_detect = chi2.isf(alpha, bank.ranks)
        self.h_clear = chi2.isf(settings.clear_alpha, bank.ranks)
        self.warmup_ticks = round(settings.warmup_s / dt)
        masks = [_mask(s) for s in bank.left_out]
        self.observer_of_mask = np.full(1 << N_SPEED, -1)
        for j, m in enumerate(masks):
            self.observer_of_mask[m] = j
        self.masks = np.array(masks)
        self.sizes = np.array([len(s) for s in bank.left_out])
        self.flagged = np.zeros(n, dtype=np.int64)  # bitmask of flagged sensors per turbine
        self.frozen = np.zeros((n, N_SPEED), dtype=bool)
        self._same_count = np.zeros((n, N_SPEED), dtype=np.int64)
        self._clear_count = np.zeros((n, N_SPEED), dtype=np.int64)
        self._y_prev: np.ndarray | None = None
        self.ticks = 0
        self.ambiguous = np.zeros(n, dtype=bool)  # no consistent observer was found at the last search

    @property
    def faulty(self) -> np.ndarray:
        return (self.flagged[:, None] >> np.arange(N_SPEED)) & 1 == 1

    @property
    def selected(self) -> np.ndarray:
        """Index of the observer matching the flagged set (−1 when no observer of the bank matches)."""
        return self.observer_of_mask[self.flagged]

    def margins(self, chi2_stat: np.ndarray) -> np.ndarray:
        """χ²_j / h_j for every observer (n, n_obs): above 1 means inconsistent."""
        return chi2_stat / self.h_detect

    def step(self, y: np.ndarray, chi2_stat: np.ndarray) -> None:
        """Update the flags from speed readings y (n, 4) and the bank's χ² statistics (n, n_obs)."""
        self._update_frozen(y)
        self.ticks += 1
        if self.ticks <= self.warmup_ticks:
            return
        frozen_mask = self.frozen @ _BITS
        self.flagged |= frozen_mask
        selected = self.observer_of_mask[self.flagged]
        rows = np.arange(self.n)
        sel_stat = np.where(selected >= 0, chi2_stat[rows, np.maximum(selected, 0)], np.inf)
        sel_h = np.where(selected >= 0, self.h_detect[np.maximum(selected, 0)], 1.0)
        inconsistent = sel_stat > sel_h
        for row in np.flatnonzero(inconsistent):
            self._search(row, chi2_stat[row], int(frozen_mask[row]))
        if self.flagged.any():
            self._clear(chi2_stat, frozen_mask, inconsistent)

    def _search(self, row: int, stat: np.ndarray, frozen: int) -> None:
        """Select the consistent observer that leaves out the fewest sensors (and every frozen one)."""
        current = int(self.flagged[row])
        candidates = np.flatnonzero(((self.masks & frozen) == frozen) & (self.masks != current))
        if len(candidates) == 0:  # more sensors frozen than any observer can leave out
            self.flagged[row] = current | frozen
            self.ambiguous[row] = True
            return
        ratio = stat[candidates] / self.h_detect[candidates]
        consistent = ratio <= 1.0
        self.ambiguous[row] = not consistent.any()
        pool, pool_ratio = (candidates[consistent], ratio[consistent]) if consistent.any() else (candidates, ratio)
        best = pool[np.lexsort((pool_ratio, self.sizes[pool]))[0]]
        self.flagged[row] = self.masks[best]
        self._clear_count[row] = 0

    def _clear(self, chi2_stat: np.ndarray, frozen_mask: np.ndarray, skip: np.ndarray) -> None:
        """Count consecutive consistent ticks of 'selected set + sensor s' and unflag s after clear_ticks."""
        for s in range(N_SPEED):
            bit = 1 << s
            rows = (self.flagged & bit).astype(bool) & ~skip & ((frozen_mask & bit) == 0)
            if not rows.any():
                self._clear_count[:, s] = 0
                continue
            with_s = self.observer_of_mask[self.flagged & ~bit]
            valid = rows & (with_s >= 0)
            ok = np.zeros(self.n, dtype=bool)
            idx = np.flatnonzero(valid)
            ok[idx] = chi2_stat[idx, with_s[idx]] <= self.h_clear[with_s[idx]]
            self._clear_count[:, s] = np.where(ok, self._clear_count[:, s] + 1, 0)
            done = self._clear_count[:, s] >= self.s.clear_ticks
            self.flagged[done] &= ~bit
            self._clear_count[done, s] = 0

    def _update_frozen(self, y: np.ndarray) -> None:
        if self._y_prev is not None:
            same = y == self._y_prev
            self._same_count = np.where(same, self._same_count + 1, 0)
            self.frozen = self._same_count >= self.s.frozen_ticks - 1
        self._y_prev = y.copy()
