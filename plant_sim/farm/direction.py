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
unwrapped (continuous through 360°); every consumer reads it modulo 360°. θ(t) is the direction at the mast; the
turbines see it as the wind carries it across the farm (below): a farm 5.6 km deep (Horns Rev 1) feels a veer at
its far edge about 10 minutes after its front row at 9 m/s.

**The direction is carried with the wind** (Taylor's frozen field, for the direction as for the turbulence). The
air that passed the mast at time τ carries the direction θ(τ) the mast saw then, and travels at the mean wind v̄
along the profile's direction θ_p(τ), the large-scale flow. Turbine t, s_t(θ) downwind of the farm's upwind edge
(its most upwind turbine for wind from θ, ``FarmLayout.wind_frame``), is d_t(θ) = d_mast + s_t(θ) from the mast
along θ, so the air that left the mast at τ reaches it when the wind has carried it that far:

.. math::  X(t) = \int_{-H}^{t} \bar v\,dt',\qquad
           A_t(τ) = X^{-1}\bigl(X(τ) + d_t(θ_p(τ))\bigr),\qquad
           τ_t(t) = \max\{τ : A_t(τ) \le t\},\qquad θ_t(t) = θ\bigl(τ_t(t)\bigr)

τ_t is the newest air that has reached the turbine: it sees the mast's frozen turbulence v_mast(τ_t) and the wind
direction θ_t, veer included. θ and v̄ are exogenous, so τ_t is computed once for the whole run
(``arrival_lookup``: A on every mast sample, its running minimum from the end, B(τ) = min_{τ' ≥ τ} A(τ'), which is
non-decreasing, and τ_t(t) = B⁻¹(t) by linear interpolation). With a steady direction and wind this is eq. (3),
τ_t = t − d_t/v̄; a step of the profile at τ₀ from θ₁ to θ₂ reaches turbine t at τ₀ + d_t(θ₂)/v̄ (the new air's
own path), the front row first. With a gusting v̄ the field a turbine sees was carried exactly d_t since it passed
the mast, and τ_t only moves forward (eq. (3)'s t − d/v̄(t), which the fixed-direction plant keeps bit for bit,
runs backwards when v̄ rises quickly: ``docs/farm.md`` §1.9). Where newer air overtakes older air (its path is
shorter by more than the wind carries it between the two: a quick swing of the profile across a deep farm) the
turbine takes the newer; where it falls behind, the turbine holds the last air that arrived until the newer
catches up.

The random veer is carried but does not bend the path: the Gauss–Markov veer moves by σ_v √(2Δt/T_v) every
sample, and taking each sample's direction as its air's straight path makes the air overtake itself all the time
(on ``farm-hornsrev1-veer``, 2 runs of seed 77, τ_t then jumped by up to 25 s and stood still in 42 % of the
samples; along θ_p it moves by 0.1 s ± 0.05 s every sample). Leaving the veer out of the path shifts an arrival by
s_t(θ_p + veer) − s_t(θ_p) over v̄: rms 8.2 s (99th percentile 26 s) of travel times up to 850 s on that farm,
rms 2.4 s (p99 7.9 s) on ``farm-3x3-veer`` (4 runs, seed 77).

**Wakes along the direction the air carries.** The wake of i that reaches j now travelled from i to j in the air
that j sees, which left the mast at τ_j and passed i a time x_ij/v̄ earlier: in a frozen field i saw that same
air then, τ_i(t − x_ij/v̄) = τ_j(t). So the pair is looked up at the downstream turbine's direction,

.. math::  θ_{ij}(t) = θ_j(t) = θ\bigl(τ_j(t)\bigr),\qquad x_{ij} = s_j(θ_j) - s_i(θ_j),

which is also i's direction when it shed that wake (``WakeTables.waked_per_turbine``); the pair's C_T is i's of
x_ij/v̄ before. Wake-added turbulence intensity is not delayed (``plant_sim.farm.wake_tables``): TI_i is taken at
i's own direction.

The met-mast vane reads θ(t) at the mast, modulo 360°, plus its white noise (``mast_direction_noise_deg``).
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

    ``deg[r, i]`` is run r's direction at t_i = i·FARM_DT_S − HISTORY_S (the grid of ``MastSeries``), ``path_deg[i]``
    the profile's alone (the direction the air that passed the mast then travels along); ``varies``
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
            self.path_deg = np.full(n, plant.direction_deg)
            return
        profile = plant.direction_profile_deg(np.maximum(self.t, 0.0))
        self.path_deg = profile  # the air's path: the profile's large-scale direction (module docstring)
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

    def at_time(self, runs: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Direction (deg, unwrapped) of runs ``runs`` at times ``t`` (same shape), linear between samples (as
        ``MastSeries.at``, clamped to the series)."""
        x = (np.asarray(t) - self.t[0]) / FARM_DT_S
        i = np.clip(x.astype(np.intp), 0, self.deg.shape[1] - 2)
        frac = np.clip(x - i, 0.0, 1.0)
        return self.deg[runs, i] * (1.0 - frac) + self.deg[runs, i + 1] * frac


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


def arrival_lookup(
    times: np.ndarray,
    advected: np.ndarray,
    path_deg: np.ndarray,
    layout: FarmLayout,
    mast_distance_m: float,
    query_times: np.ndarray,
) -> np.ndarray:
    """τ_t (s), shape (Q, N): for one run, the newest air each turbine has seen at each of ``query_times`` (Q,), the
    time it passed the mast (module docstring). ``times`` (S,) the mast samples, ``advected`` X on them (increasing),
    ``path_deg`` θ_p on them (unwrapped, the direction the air travels along); ``mast_distance_m`` from the mast to
    the farm's upwind edge.

    A_t(τ_i) = X⁻¹(X_i + d_t(θ_p,i)) for every sample i (past the series' end at its last v̄), B its running
    minimum from the end; τ_t(t) = B⁻¹(t) on the last sample of each run of equal B (np.interp, clamped at the
    first sample)."""
    d = mast_distance_m + downwind_distances(layout, path_deg)  # (S, N)
    reach = advected[:, None] + d
    arrival = np.interp(reach, advected, times)  # (S, N) A_t(τ_i); beyond the series at its last mean wind:
    speed = (advected[-1] - advected[-2]) / (times[-1] - times[-2])
    arrival = np.where(reach > advected[-1], times[-1] + (reach - advected[-1]) / speed, arrival)
    earliest = np.minimum.accumulate(arrival[::-1], axis=0)[::-1]  # B_t(τ_i) = min over i' ≥ i
    out = np.empty((len(query_times), d.shape[1]))
    for t in range(d.shape[1]):
        b = earliest[:, t]
        last = np.append(b[1:] > b[:-1], True)  # the newest sample of each equal B
        out[:, t] = np.interp(query_times, b[last], times[last])
    return out
