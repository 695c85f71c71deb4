"""Detection of displacement offsets from the reconstruction: the flags behind DETECTION / RECOVERY for u_p, u_M.

Rule (per actuator j, per turbine): flag when |f̂_filt,j| > θ_j for ``on_samples`` consecutive samples; unflag
when |f̂_filt,j| < ``off_ratio`` · θ_j for ``off_samples`` consecutive samples (time hysteresis, so a flagged
fault does not chatter). The release level is θ itself by default: θ lies above the fault-free noise, so a
lower release level (tried: θ/2) kept the flag set for the rest of the run under ±2 % noise, where |f̂_filt|
keeps touching θ/2. Nothing is flagged in the first ``warmup_s``.

**θ is a design value, fixed before any run** (``design_thresholds``), from three stated inputs and no data:

* the sensors' accuracy ``sensor_noise_pct`` (relative error within ±a; 0.1 % for the nominal encoders and
  LVDTs, 2 % for the paper's noise case), turned into the standard deviation σ_j of the fault-free f̂_filt,j by
  the observer's own noise response (``service.hydro.noise``: σ_j = (a/√3) ‖h_j‖₂);
* the design false-alarm rate R = ``false_alarms_per_1000s`` (default 0.01 per 1000 s for both actuators
  together, ten times below the requirement of 0.1). Every onset needs at least one sample with
  |f̂_filt,j| > θ_j, so the onset rate is at most the rate of such samples; with f̂_filt taken as Gaussian,
  2 Q(θ_j/σ_j)/dt ≤ R/(2 · 1000 s) per actuator gives θ_j = σ_j Q⁻¹(R dt/(4 · 1000 s)) (5.45 σ at the
  defaults). Noise within ±a has lighter tails than that Gaussian (it cannot exceed a ‖h_j‖₁, 2.5 σ_j at
  τ = 0.05 s), and the persistence of ``on_samples`` is not counted, so R is an upper bound;
* the smallest offset worth flagging, ``min_offset`` (a hundredth of a stroke): θ_j ≥ min_offset.

With the shipped observer settings: θ = 0.01 for both actuators in the 0.1 % scenarios (the floor; the rate alone
gives 0.0035 with their filter (37') of two 0.025-s stages) and θ = 0.029 in hydro-noise (±2 %, (37') of two
0.05-s stages). ``threshold`` sets θ by hand instead.

``hold_offset`` is read by the supervisor, not by the flags: while actuator j is flagged its correction becomes the
mean of f̂_a since the flag once that mean is less noisy than f̂_filt, and θ_j decides when the mean is stale
(``service.hydro.offset_hold``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np

from service.hydro.noise import NoiseResponse
from service.hydro.smo import Reconstruction
from wwcore.options import Bounds
from wwcore.quantiles import norm_isf

N_ACTUATORS = 2  # u_p, u_M


@dataclass(frozen=True)
class DetectionSettings:
    """Options of the ``threshold`` detector (``[supervisor.params]``); ``Bounds``: the accepted range."""

    # design rate of false alarms, both actuators together
    false_alarms_per_1000s: Annotated[float, Bounds(gt=0.0, le=1000.0, unit="1/1000 s")] = 0.01
    # the sensors' relative accuracy: each reading within ±sensor_noise_pct % of the truth (design datum)
    sensor_noise_pct: Annotated[float, Bounds(ge=0.0, le=10.0, unit="%")] = 0.1
    # smallest offset worth flagging: the floor of θ
    min_offset: Annotated[float, Bounds(ge=0.0, le=1.0, unit="stroke")] = 0.01
    # θ for [u_p, u_M] set by hand instead of the design
    threshold: Annotated[tuple[float, float] | None, Bounds(gt=0.0, le=1.0, unit="stroke")] = None
    on_samples: Annotated[int, Bounds(ge=1, le=1000, unit="samples")] = 5  # above θ to flag (50 ms at 100 Hz)
    off_ratio: Annotated[float, Bounds(gt=0.0, le=1.0)] = 1.0  # release level as a fraction of θ
    off_samples: Annotated[int, Bounds(ge=1, le=100_000, unit="samples")] = 50  # below it to unflag (0.5 s)
    warmup_s: Annotated[float, Bounds(ge=0.0, le=600.0, unit="s")] = 1.0  # observer convergence
    # while flagged, correct with the mean of f̂_a since the flag once it beats f̂_filt (service.hydro.offset_hold)
    hold_offset: bool = False


def design_thresholds(response: NoiseResponse, settings: DetectionSettings, dt: float) -> np.ndarray:
    """θ (2,) from the noise response, the sensors' accuracy and the design rate (module docstring)."""
    if settings.threshold is not None:
        return np.asarray(settings.threshold, dtype=float)
    per_sample = settings.false_alarms_per_1000s * dt / 1000.0 / N_ACTUATORS  # P(|f̂_filt,j| > θ_j) per sample
    z = float(norm_isf(per_sample / 2.0))
    return np.maximum(z * response.sigma(settings.sensor_noise_pct), settings.min_offset)


class ThresholdDetector:
    """Hysteresis detector over the filtered reconstruction, for n turbines (one per run)."""

    def __init__(self, *, context, options: dict | None = None):
        self.s = DetectionSettings(**(options or {}))
        self.n = context.n
        self.noise = context.noise_response()
        self.theta = design_thresholds(self.noise, self.s, context.dt)
        self.sigma = self.noise.sigma(self.s.sensor_noise_pct)  # the predicted fault-free σ of f̂_filt
        self.flagged = np.zeros((self.n, N_ACTUATORS), dtype=bool)
        self._above = np.zeros((self.n, N_ACTUATORS), dtype=int)
        self._below = np.zeros((self.n, N_ACTUATORS), dtype=int)

    def step(self, t: float, rec: Reconstruction) -> np.ndarray:
        """Update with the reconstruction at time t (its f̂_filt, (n, 2)); return the flags (n, 2)."""
        if t < self.s.warmup_s:
            return self.flagged
        mag = np.abs(rec.f_filt)
        self._above = np.where(mag > self.theta, self._above + 1, 0)
        self._below = np.where(mag < self.s.off_ratio * self.theta, self._below + 1, 0)
        rise = ~self.flagged & (self._above >= self.s.on_samples)
        fall = self.flagged & (self._below >= self.s.off_samples)
        self.flagged = (self.flagged | rise) & ~fall
        return self.flagged


class NoDetector:
    """Flags nothing (the reconstruction and the compensation still run)."""

    def __init__(self, *, context, options: dict | None = None):
        self.flagged = np.zeros((context.n, N_ACTUATORS), dtype=bool)

    def step(self, t: float, rec: Reconstruction) -> np.ndarray:
        return self.flagged
