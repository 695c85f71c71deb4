"""Speed-sensor fault detection and isolation from the observer bank's residuals (seed 000, Section 3).

In the manner of Odgaard & Stoustrup (2010): each observer's residual is decoupled from the unknown input, so
it stays at its noise level unless a sensor it uses is faulty. The decision logic is a generalised observer
scheme on the bank:

* **Consistency.** Observer j is consistent at tick n when both its whitened residual's χ² statistic
  χ²_j[n] = ‖W_j r_j[n]‖² and the sum of the last ``window`` of them stay below their thresholds. The sum is
  what catches small biases: a UIO cannot predict the rotor speed one tick ahead (any change might be
  aerodynamic torque), so a bias of a few σ on a rotor-speed sensor shows in the residuals only as the
  observers' states drift from it over several ticks.
* **Detection and isolation.** While the selected observer (the one that leaves out the flagged sensors) is
  consistent, nothing changes. When it is not, the supervisor searches the whole bank and selects the
  consistent observer that leaves out the fewest sensors (ties: smallest statistic over threshold); the
  sensors it leaves out are the isolated faults. Searching the whole bank, not only observers that leave out
  more, lets an early isolation that missed a small second fault correct itself at the next inconsistency.
* **Fault end.** A flagged sensor is cleared when the window sum of the observer that uses it again (selected
  set plus that sensor) falls below the clearing threshold.
* **Frozen signals.** A reading that does not change at all for ``frozen_ticks`` ticks is flagged at once
  (fixed-value and stuck faults carry no noise; this also catches a fixed value that happens to equal the
  truth, which no residual can see).

Thresholds come from the false-alarm budget (PARAMETERS.md d), not from fault data. A design rate of false
alarms per 1000 s (default 0.01: the requirement is 1, the aim none) gives α = rate·Ts/1000 per tick, split
evenly between the single-tick and the window test: h_j = χ²⁻¹_{rank_j}(1 − α/2), and for the window sum a
scaled χ², c·χ²_ν, with the sum's exact mean and variance from the residual's closed-form autocovariance
(Satterthwaite: c = Var/2E, ν = 2E²/Var; ``uio``). Clearing uses α_clear (default 1 %) on the window sum.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np

from service.plugins import AlgorithmOptionError
from service.turbine.bank import BankDesign
from service.turbine.frozen import FrozenReadings
from wwcore.channels import SPEED_SENSORS
from wwcore.options import Bounds
from wwcore.quantiles import chi2_isf

N_SPEED = len(SPEED_SENSORS)
_BITS = 1 << np.arange(N_SPEED)
_SENSORS_OF_MASK = (np.arange(1 << N_SPEED)[:, None] >> np.arange(N_SPEED)) & 1 == 1  # (16, 4): bitmask → flags


@dataclass(frozen=True)
class FDISettings:
    """Options of the speed-sensor FDI (``[supervisor.params]``); each field's ``Bounds`` is its accepted range."""

    # design rate of the detection tests (requirement: < 1, aim: none)
    false_alarms_per_1000s: Annotated[float, Bounds(gt=0.0, le=1000.0, unit="1/1000 s")] = 0.01
    # probability that a healthy sensor's window fails the clearing test
    clear_alpha: Annotated[float, Bounds(gt=0.0, lt=1.0)] = 0.01
    window: Annotated[int, Bounds(ge=1, le=1000, unit="ticks")] = 4  # ticks summed by the window test
    # ticks summed by the clearing test (≤ window): ends recognised a tick sooner
    clear_window: Annotated[int, Bounds(ge=1, le=1000, unit="ticks")] = 3
    # identical consecutive readings that mark a sensor frozen
    frozen_ticks: Annotated[int, Bounds(ge=2, le=1000, unit="ticks")] = 3
    # no decisions while the observers converge from their initial state
    warmup_s: Annotated[float, Bounds(ge=0.0, le=600.0, unit="s")] = 5.0


def window_threshold(autocov: np.ndarray, window: int, alpha: float) -> float:
    """Upper α-quantile of Σ_{i<window} ‖w[n−i]‖² for a whitened residual with autocovariance ``autocov``.

    E = window·rank; Var = Σ_i Σ_j 2 tr(R_{|i−j|} R_{|i−j|}ᵀ) (Gaussian quadratic forms); the sum is taken as
    c·χ²_ν with c = Var/(2E), ν = 2E²/Var (Satterthwaite), which is exact for a white residual.
    """
    rank = autocov.shape[1]
    mean = window * rank
    lag_power = [2.0 * float(np.trace(autocov[k] @ autocov[k].T)) for k in range(window)]
    var = sum(lag_power[abs(i - j)] for i in range(window) for j in range(window))
    c, nu = var / (2.0 * mean), 2.0 * mean**2 / var
    return float(c * chi2_isf(alpha, nu))


def _mask(left_out: frozenset[str]) -> int:
    return sum(1 << SPEED_SENSORS.index(s) for s in left_out)


class SpeedSensorFDI:
    """Flags faulty speed sensors for n turbines; ``faulty`` (n, 4) bool in SPEED_SENSORS order."""

    def __init__(self, bank: BankDesign, n: int, dt: float, settings: FDISettings = FDISettings()):
        self.bank = bank
        self.s = settings
        self.n = n
        alpha = settings.false_alarms_per_1000s * dt / 1000.0
        ranks = bank.ranks[: bank.n_isolating]
        observers = bank.observers[: bank.n_isolating]
        self.h_detect = chi2_isf(alpha / 2.0, ranks)
        self.h_window = np.array([window_threshold(o.autocov, settings.window, alpha / 2.0) for o in observers])
        if not 1 <= settings.clear_window <= settings.window:
            raise AlgorithmOptionError(
                f"clear_window must be 1 … window ({settings.window}), not {settings.clear_window}"
            )
        self.h_clear = np.array(
            [window_threshold(o.autocov, settings.clear_window, settings.clear_alpha) for o in observers]
        )
        self._history = np.zeros((settings.window, n, bank.n_isolating))  # ring of the last χ² statistics
        self._window_sum = np.zeros((n, bank.n_isolating))
        self.warmup_ticks = round(settings.warmup_s / dt)
        masks = [_mask(s) for s in bank.left_out]
        self.observer_of_mask = np.full(1 << N_SPEED, -1)
        for j, m in enumerate(masks):
            self.observer_of_mask[m] = j
        self.masks = np.array(masks)
        self.sizes = np.array([len(s) for s in bank.left_out])
        self.flagged = np.zeros(n, dtype=np.int64)  # bitmask of flagged sensors per turbine
        self.readings = FrozenReadings((n, N_SPEED), settings.frozen_ticks)
        self.ticks = 0
        self.ambiguous = np.zeros(n, dtype=bool)  # no consistent observer was found at the last search
        self._rows = np.arange(n)
        # Cheap state for the common tick on which no sensor is flagged or frozen (each skips a few numpy calls):
        self.ratio = np.zeros((n, bank.n_isolating))  # ``margins`` of the last step
        self._maybe_flagged = False  # False only while no row has a flagged sensor
        self._all_healthy = int(self.observer_of_mask[0])  # the observer that leaves nothing out
        self._no_frozen = np.zeros(n, dtype=np.int64)

    @property
    def faulty(self) -> np.ndarray:
        return _SENSORS_OF_MASK[self.flagged]

    @property
    def selected(self) -> np.ndarray:
        """Index of the observer matching the flagged set (−1 when no observer of the bank matches)."""
        return self.observer_of_mask[self.flagged]

    def margins(self, chi2_stat: np.ndarray) -> np.ndarray:
        """max(χ²_j/h_j, Σχ²_j/h_window,j) for every isolating observer (n, n_isolating): above 1 is inconsistent."""
        return np.maximum(chi2_stat[:, : self.bank.n_isolating] / self.h_detect, self._window_sum / self.h_window)

    def step(self, y: np.ndarray, chi2_stat: np.ndarray) -> None:
        """Update the flags from speed readings y (n, 4) and the bank's χ² statistics (n, n_obs)."""
        chi2_stat = chi2_stat[:, : self.bank.n_isolating]
        slot = self.ticks % self.s.window
        self._window_sum += chi2_stat - self._history[slot]
        self._history[slot] = chi2_stat
        any_frozen = self.readings.push(y)
        self.ticks += 1
        self.ratio = ratio = np.maximum(chi2_stat / self.h_detect, self._window_sum / self.h_window)
        if self.ticks <= self.warmup_ticks:
            return
        if any_frozen:
            frozen_mask = self.readings.frozen @ _BITS
            self.flagged |= frozen_mask
            self._maybe_flagged = True
        else:
            frozen_mask = self._no_frozen
        if self._maybe_flagged:
            selected = self.observer_of_mask[self.flagged]
            usable = np.maximum(selected, 0)
            inconsistent = (ratio[self._rows, usable] > 1.0) | (selected < 0)
        else:  # every row selects the observer that uses all four sensors
            inconsistent = ratio[:, self._all_healthy] > 1.0
        if inconsistent.any():
            for row in np.flatnonzero(inconsistent):
                self._search(row, ratio[row], int(frozen_mask[row]))
            self._maybe_flagged = True
        if self._maybe_flagged:
            if self.flagged.any():
                self._clear(frozen_mask, inconsistent)
            self._maybe_flagged = bool(self.flagged.any())

    def _search(self, row: int, ratio: np.ndarray, frozen: int) -> None:
        """Select the consistent observer that leaves out the fewest sensors (and every frozen one)."""
        current = int(self.flagged[row])
        candidates = np.flatnonzero(((self.masks & frozen) == frozen) & (self.masks != current))
        if len(candidates) == 0:  # more sensors frozen than any observer can leave out
            self.flagged[row] = current | frozen
            self.ambiguous[row] = True
            return
        ratio = ratio[candidates]
        consistent = ratio <= 1.0
        self.ambiguous[row] = not consistent.any()
        pool, pool_ratio = (candidates[consistent], ratio[consistent]) if consistent.any() else (candidates, ratio)
        self.flagged[row] = self.masks[pool[np.lexsort((pool_ratio, self.sizes[pool]))[0]]]

    def _clear(self, frozen_mask: np.ndarray, skip: np.ndarray) -> None:
        """Unflag sensor s where the window sum of 'selected set + s' is below the clearing threshold."""
        for s in range(N_SPEED):
            bit = 1 << s
            rows = np.flatnonzero((self.flagged & bit).astype(bool) & ~skip & ((frozen_mask & bit) == 0))
            if len(rows) == 0:
                continue
            with_s = self.observer_of_mask[self.flagged[rows] & ~bit]
            rows, with_s = rows[with_s >= 0], with_s[with_s >= 0]
            recent = self._history[(self.ticks - 1 - np.arange(self.s.clear_window)) % self.s.window]
            done = rows[recent[:, rows, with_s].sum(axis=0) <= self.h_clear[with_s]]
            self.flagged[done] &= ~bit
