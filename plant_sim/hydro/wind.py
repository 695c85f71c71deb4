"""Hub-height turbulent wind for the hydrostatic turbine: a mean profile plus first-order (Ornstein–Uhlenbeck)
turbulence, one independent stream per turbine of the batch.

The turbulence u_t has standard deviation σ_u = TI · v̄ and integral time scale T = L/v̄ (a Kaimal spectrum
S(f) = 4σ²(L/v̄)/(1 + 6fL/v̄)^{5/3} has the same low-frequency level 4σ²T as the first-order process, which
rolls off as f⁻² instead of f^{−5/3}; the rotor's spatial averaging removes most of that difference). It is
discretised exactly:

    u_{k+1} = a u_k + σ_u √(1 − a²) ξ_k,   a = exp(−dt/T),   ξ_k ~ N(0, 1),

and starts from its stationary distribution. Shear and tower shadow of ``WindSpec`` do not apply to this
rotor-effective model and are ignored (documented in docs/hydro.md).
"""

from __future__ import annotations

import numpy as np

from wwcore.scenario.wind import WindSpec

CHUNK_TICKS = 1000
"""Random numbers are drawn for this many ticks at a time, so the per-tick work is one multiply-add."""


class HydroWind:
    """Rotor-effective wind speed for n turbines, each drawing from its own generator."""

    def __init__(self, spec: WindSpec, dt: float, rngs: list[np.random.Generator]):
        self.spec = spec
        self.dt = dt
        self.rngs = rngs
        self.n = len(rngs)
        times, speeds = zip(*spec.mean, strict=True)
        self._t_mean = np.array(times, dtype=float)
        self._v_mean = np.array(speeds, dtype=float)
        v0 = self.mean(0.0)
        self._sigma0 = spec.turbulence_intensity * v0
        self.turbulence = np.array([rng.standard_normal() for rng in rngs]) * self._sigma0
        self._buffer = np.zeros((self.n, 0))
        self._pos = 0

    def mean(self, t: float) -> float:
        """Mean speed v̄(t), m/s: piecewise linear through the scenario's points, held after the last."""
        return float(np.interp(t, self._t_mean, self._v_mean))

    def _draw(self) -> None:
        self._buffer = np.stack([rng.standard_normal(CHUNK_TICKS) for rng in self.rngs])
        self._pos = 0

    def speed(self, t: float) -> np.ndarray:
        """v(t) (n,), m/s, at the current tick (before ``advance``)."""
        return np.maximum(self.mean(t) + self.turbulence, 0.5)

    def advance(self, t: float) -> None:
        """Move the turbulence from t to t + dt (exact OU step with the time scale at v̄(t))."""
        if self._pos >= self._buffer.shape[1]:
            self._draw()
        v_bar = max(self.mean(t), 0.5)
        sigma = self.spec.turbulence_intensity * v_bar
        a = np.exp(-self.dt * v_bar / self.spec.length_scale_m)
        self.turbulence = a * self.turbulence + sigma * np.sqrt(1.0 - a * a) * self._buffer[:, self._pos]
        self._pos += 1
