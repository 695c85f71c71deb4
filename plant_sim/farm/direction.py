r"""The farm's wind direction over time: the scenario's profile plus a slow random veer, and the travel geometry.

**Direction.** Per Monte Carlo run, the wind comes from

.. math::  θ(t) = θ_p(t) + σ_v\,\mathrm{clip}\bigl(z_v(t), -4, 4\bigr),\qquad
           \dot z_v = -z_v/T_v + \sqrt{2/T_v}\,w

θ_p the scenario's ``wind_direction_profile`` (piecewise linear on the unwrapped angles, ``wwcore.scenario.wind``)
or its constant direction; z_v a unit-variance first-order Gauss–Markov (Ornstein–Uhlenbeck) process of
correlation time T_v = ``veer_time_s``, sampled exactly at the farm rate (z_k = φ z_{k−1} + √(1 − φ²) w_k,
φ = e^{−Δt/T_v}, z at −``HISTORY_S`` drawn from the stationary law), so its autocorrelation is e^{−|τ|/T_v} and its
stationary σ is σ_v = ``veer_sigma_deg``. The veer is held within ±4 σ_v (``VEER_BOUND_SIGMA``; a draw beyond
happens once in 16 000 independent samples and shortens σ by under 10⁻³ of itself), so that the wake tables can
cover every direction a run reaches: the profile's range ± 4 σ_v (``FarmPlant.direction_sector_deg``). The veer has a
random stream of its own (``plant_sim.farm.plant.veer_stream``): switching it on changes no other draw. θ is kept
unwrapped (continuous through 360°); every consumer reads it modulo 360°. The direction is one per farm at a time
(a farm a few kilometres across turns as one: the veer's correlation time is minutes, the wind crosses it in
minutes too, the first-order simplification of a direction field that is itself advected).

**Travel geometry along the actual direction.** At every farm sample the plant recomputes, for the current θ,
each turbine's distance s_t(θ) downwind of the farm's upwind edge (its most upwind turbine, ``FarmLayout.wind_frame``)
and the pair distances x_ij(θ) = s_j − s_i. Turbine t sees the mast's frozen turbulence (Taylor's hypothesis),
carried at the mean wind v̄ along the *current* direction: the field now at distance d_t = d_mast + s_t(θ(t)) from
the mast passed the mast when the wind had carried it d_t less far,

.. math::  X(t) = \int_{-H}^{t} \bar v\,dt',\qquad
           τ_t(t) = \max\Bigl(τ_t(t - Δt),\; X^{-1}\bigl(X(t) - d_t\bigr)\Bigr)

and the turbine sees v_mast(τ_t). With a fixed distance τ_t only moves forward, whatever v̄ does (eq. (3)'s
t − d/v̄(t), which the fixed-direction plant keeps bit for bit, runs backwards when v̄ rises quickly:
``docs/farm.md`` §1.9). When the direction swings a
turbine away from the upwind edge faster than the wind carries the field (ṡ_t > v̄: a far turbine under a quick
veer) the advected lookup would run backwards through the field the turbine has already seen; the maximum holds
the sample it has until the geometry catches up (no time reversal). The wake of i reaches j a time x_ij(θ)/v̄
after it left i (the pair's delayed C_T, as with a fixed direction).

The met-mast vane reads θ(t) modulo 360° plus its white noise (``mast_direction_noise_deg``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import signal

from plant_sim.farm.wind import HISTORY_S, MIN_MEAN_WIND
from wwcore.layout import FarmLayout
from wwcore.scenario.farm import FARM_DT_S, VEER_BOUND_SIGMA, FarmPlant


def gauss_markov(rng: np.random.Generator, samples: int, dt: float, time_constant: float) -> np.ndarray:
    """A unit-variance first-order Gauss–Markov sequence of ``samples`` at step ``dt`` (exact discretisation of
    dz = −z/T dt + √(2/T) dW), started from its stationary law."""
    phi = math.exp(-dt / time_constant)
    w = rng.standard_normal(samples)
    w[0] /= math.sqrt(1.0 - phi * phi)  # z_0 ~ N(0, 1)
    return signal.lfilter([math.sqrt(1.0 - phi * phi)], [1.0, -phi], w)


class DirectionSeries:
    """The wind direction θ (deg, unwrapped) of each run at every farm sample from −HISTORY_S to the run's end.

    ``deg[r, i]`` is run r's direction at t_i = i·FARM_DT_S − HISTORY_S (the grid of ``MastSeries``); ``varies``
    says whether it moves at all (a profile through distinct directions, or veer): when it does not, ``deg`` is the
    scenario's constant direction exactly and the plant keeps its fixed geometry.
    """

    def __init__(
        self, plant: FarmPlant, rngs: Sequence[np.random.Generator] | None, runs: int, duration_s: float
    ) -> None:
        dt = FARM_DT_S
        self.offset = round(HISTORY_S / dt)  # index of t = 0
        n = self.offset + math.ceil(duration_s / dt) + 2
        self.t = np.arange(n) * dt - HISTORY_S
        self.varies = plant.direction_varies
        if not self.varies:
            self.deg = np.full((runs, n), plant.direction_deg)
            return
        profile = plant.direction_profile_deg(np.maximum(self.t, 0.0))
        self.deg = np.repeat(profile[None, :], runs, axis=0)
        sigma = plant.veer_sigma_deg
        if sigma > 0.0:
            if rngs is None or len(rngs) != runs:
                raise ValueError("a random veer needs one random stream per run")
            for r, rng in enumerate(rngs):
                z = gauss_markov(rng, n, dt, plant.veer_time_s)
                self.deg[r] += sigma * np.clip(z, -VEER_BOUND_SIGMA, VEER_BOUND_SIGMA)

    def at(self, runs: np.ndarray, j: int) -> np.ndarray:
        """Direction (deg, unwrapped) of runs ``runs`` at farm sample j (t = j·FARM_DT_S)."""
        return self.deg[runs, self.offset + j]


def downwind_distances(layout: FarmLayout, direction_deg: np.ndarray) -> np.ndarray:
    """s_t(θ) (m), shape (..., N): each turbine's distance downwind of the farm's most upwind turbine for wind from
    ``direction_deg`` (...), as ``FarmLayout.wind_frame`` for one direction."""
    th = np.radians(np.asarray(direction_deg, dtype=float))[..., None]
    s = -layout.x * np.sin(th) - layout.y * np.cos(th)
    return s - s.min(axis=-1, keepdims=True)


def advected_distance(vbar: np.ndarray) -> np.ndarray:
    """X (m), shape of ``vbar`` (..., samples): how far the mean wind has carried the frozen field past the mast since
    the first sample, X_i = Σ_{k<i} max(v̄_k, MIN_MEAN_WIND) Δt (increasing)."""
    v = np.maximum(vbar, MIN_MEAN_WIND) * FARM_DT_S
    return np.concatenate([np.zeros_like(v[..., :1]), np.cumsum(v[..., :-1], axis=-1)], axis=-1)


def lookup_times(
    x_now: float, distances_m: np.ndarray, advected: np.ndarray, times: np.ndarray, previous: np.ndarray | None
) -> np.ndarray:
    """τ = max(previous, X⁻¹(X(t) − d)) (s) of one run, ``distances_m`` (..., N) from the mast: when the mast saw the
    frozen field now at each point (module docstring); ``x_now`` = X(t), ``advected`` X on the sample ``times``
    (np.interp clamps at the first sample, −HISTORY_S)."""
    tau = np.interp(x_now - distances_m, advected, times)
    return tau if previous is None else np.maximum(tau, previous)
