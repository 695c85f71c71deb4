"""Detection of displacement offsets from the reconstruction: DETECTION / RECOVERY events for u_p and u_M.

Rule (per actuator j, per turbine): flag when |f̂_filt,j| > θ_j for ``on_samples`` consecutive samples; unflag
when |f̂_filt,j| < ``off_ratio`` · θ_j for ``off_samples`` consecutive samples (time hysteresis, so a flagged
fault does not chatter). The release level is θ itself by default: θ lies above the fault-free noise, so a
lower release level (tried: θ/2) kept the flag set for the rest of the run under ±2 % noise, where |f̂_filt|
keeps touching θ/2. Nothing is flagged in the first ``warmup_s``.

θ_j is derived from fault-free statistics, never from fault times: ``threshold_from_quiet`` takes the largest
|f̂_filt,j| seen over fault-free runs and multiplies it by a margin, so the false-alarm rate on data like the
calibration data is below one per the calibration's length (≥ 1000 s in the evaluator). A floor keeps θ
above the size of offsets that do not matter (a hundredth of a stroke).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wwcore.events import Event, EventType
from wwcore.hydro_params import FAULT_TARGETS


@dataclass(frozen=True)
class DetectionSettings:
    threshold: tuple[float, float] = (0.03, 0.03)  # –, θ for [u_p, u_M]; the evaluator calibrates them
    on_samples: int = 5  # consecutive samples above θ to flag (50 ms at 100 Hz)
    off_ratio: float = 1.0  # release level as a fraction of θ
    off_samples: int = 50  # consecutive samples below the release level to unflag (0.5 s)
    warmup_s: float = 1.0  # s, observer convergence


def threshold_from_quiet(max_abs: np.ndarray, margin: float = 1.5, floor: float = 0.01) -> tuple[float, float]:
    """θ_j = max(margin · max |f̂_filt,j| over fault-free data, floor)."""
    theta = np.maximum(margin * np.asarray(max_abs, dtype=float), floor)
    return float(theta[0]), float(theta[1])


class OffsetDetector:
    """Hysteresis detector over the filtered reconstruction, for n turbines (one per run)."""

    def __init__(self, n: int, run_ids: list[int], settings: DetectionSettings):
        self.n = n
        self.run_ids = run_ids
        self.s = settings
        self.theta = np.asarray(settings.threshold, dtype=float)
        self.flagged = np.zeros((n, 2), dtype=bool)
        self._above = np.zeros((n, 2), dtype=int)
        self._below = np.zeros((n, 2), dtype=int)
        self.events: list[Event] = []

    def step(self, t: float, f_filt: np.ndarray) -> np.ndarray:
        """Update with f̂_filt (n, 2) at time t; return the flags (n, 2)."""
        if t < self.s.warmup_s:
            return self.flagged
        mag = np.abs(f_filt)
        self._above = np.where(mag > self.theta, self._above + 1, 0)
        self._below = np.where(mag < self.s.off_ratio * self.theta, self._below + 1, 0)
        rise = ~self.flagged & (self._above >= self.s.on_samples)
        fall = self.flagged & (self._below >= self.s.off_samples)
        if rise.any() or fall.any():
            for i, j in zip(*np.nonzero(rise | fall), strict=True):
                kind = EventType.DETECTION if rise[i, j] else EventType.RECOVERY
                detail = {"f_hat_filt": float(f_filt[i, j]), "threshold": float(self.theta[j])}
                self.events.append(Event(t, kind, 1, FAULT_TARGETS[j], self.run_ids[i], detail))
            self.flagged = (self.flagged | rise) & ~fall
        return self.flagged

    def drain(self) -> list[Event]:
        out, self.events = self.events, []
        return out
