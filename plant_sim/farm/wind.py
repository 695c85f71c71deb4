r"""Wind of the farm (PARAMETERS.md b): met mast, propagation delays, the row model's wakes, per-turbine turbulence.

The wakes described here are the row model (``wake_model = "rows"``, the paper's). FLORIS's Gauss and Jensen wakes
(``plant_sim.farm.wakes.TableWakes``) replace ``RowWakes`` behind the same ``FarmWakes`` interface; the mast, the
turbulence and the per-tick interpolation below are the same for both.

**Free stream at the mast.** Per Monte Carlo run, the wind at the mast is the scenario's mean profile plus a slow
turbulence common to the whole farm (large eddies, frozen as they travel; Taylor's hypothesis):

.. math::  v_{mast}(t) = v_m(t) + σ_c(t)\,z(t),\qquad σ_c = \mathrm{TI}_c\, v_m,\qquad
           \dot z = -z/T_c + \sqrt{2/T_c}\,w

z is a unit-variance Ornstein–Uhlenbeck process (``coherent_time_s`` T_c), sampled exactly at the farm rate. The
mast reads v_mast + noise (σ ``mast_noise_mps``) at 10 Hz.

**Propagation** (seed 001 eq. (3)). The mean wind v̄ is the mast wind through H(s) = 1/(s + 1), and row j, at
distance d_j from the mast along the wind, sees the mast wind delayed by d_j / v̄:

.. math::  v_{free,j}(t) = v_{mast}\bigl(t - d_j/\bar v(t)\bigr),\qquad \bar v = \tfrac{1}{s+1} v_{mast}

**Wakes** (Jensen/Park, PARAMETERS.md b; SimWindFarm-style row model). Row i at distance x_ij upwind of row j
takes a fraction

.. math::  δ_{ij} = \bigl(1 - \sqrt{1 - C_{T,i}}\bigr)\Bigl(\frac{R}{R + k\,x_{ij}}\Bigr)^2

of the free stream away, with C_T,i the mean thrust coefficient of row i's turbines a travel time x_ij / v̄
earlier; the deficits of all upstream rows combine as the root of the sum of squares (Katić et al. 1986):
v_j = (1 − √(Σ_i δ_ij²)) v_free,j. Every turbine of a row sees the same mean wind, which is the premise of the
paper's row groups. In wind case 2 the diagonal rows are 569 m apart and a strictly geometric wake model would
wake only the turbines directly behind each other (1→5→9, 2→6, 4→8); the row model is the simplification the paper
reasons with, and is documented as such in ``docs/farm.md``.

**Thrust.** C_T,i comes from each turbine's own operating point by one-dimensional momentum theory: its power
coefficient C_p = τ_r ω_r / (½ρπR²v³) (v its mean wind, τ_r ω_r low-passed over ``CT_FILTER_S``) gives the axial
induction a from C_p = 4a(1 − a)² (a ≤ 1/3) and C_T = 4a(1 − a). A derated turbine thus casts a weaker wake, with
the travel delay.

**Turbulence of each turbine.** On top of its row's mean wind each turbine has its own Kaimal turbulence with
rotational sampling, shear and tower shadow: ``plant_sim.wind.WindField`` with the turbine's own random stream,
TI = ``wind.turbulence_intensity`` of the free-stream mean (FLORIS wakes with ``wake_added_turbulence`` scale it
by each turbine's TI_t / TI_0, ``plant_sim.farm.wakes``). The row mean replaces the scenario mean in w = v + u_0
+ u_3 cos 3ψ and in the hub reading v + u_p; between farm samples it is interpolated linearly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache
from typing import Protocol

import numpy as np
from scipy import signal

from plant_sim.turbine.trim import power_curve
from plant_sim.wind import WindField, WindSample, mean_wind
from wwcore.backend import fast_module
from wwcore.scenario.farm import FARM_DT_S, FarmPlant
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_params import TurbineParams

HISTORY_S = 1500.0  # s, longest mast-to-row and wake delay kept (d/v̄ with d ≤ 2.6 km and v̄ ≥ 1.7 m/s)
CT_FILTER_S = 5.0  # s, time constant of the aerodynamic power behind each turbine's C_T
MEAN_FILTER_S = 1.0  # s, time constant of H(s) = 1/(s + 1) [PAPER] eq. (3)
MIN_MEAN_WIND = 1.0  # m/s, floor of v̄ in the delay d/v̄
_THIRDS = np.full(3, 1.0 / 3.0)
CURVE_WINDS = np.arange(1.0, 35.01, 0.25)  # m/s, grid of the tabulated static power curve (held beyond)


# ---- closed-form pieces ---------------------------------------------------------------------------------------
def thrust_from_power_coefficient(cp: np.ndarray) -> np.ndarray:
    """C_T = 4a(1 − a) with a ∈ [0, 1/3] the root of C_p = 4a(1 − a)² (actuator disc); C_p clipped to [0, 16/27]."""
    a_grid = np.linspace(0.0, 1.0 / 3.0, 2001)
    cp_grid = 4.0 * a_grid * (1.0 - a_grid) ** 2  # increasing on [0, 1/3] up to Betz 16/27
    a = np.interp(np.clip(cp, 0.0, 16.0 / 27.0), cp_grid, a_grid)
    return 4.0 * a * (1.0 - a)


def jensen_deficit(ct: np.ndarray, distance_m: np.ndarray, radius: float, k: float) -> np.ndarray:
    """δ = (1 − √(1 − C_T)) (R / (R + k x))²: fractional speed deficit x metres behind a rotor of radius R."""
    return (1.0 - np.sqrt(1.0 - np.clip(ct, 0.0, 1.0))) * (radius / (radius + k * np.asarray(distance_m))) ** 2


@lru_cache(maxsize=4)
def static_power_curve(params: TurbineParams) -> np.ndarray:
    """Steady electrical power (W) of the benchmark turbine at rated reference on ``CURVE_WINDS``."""
    return power_curve(params, CURVE_WINDS)


def static_row_winds(plant: FarmPlant, params: TurbineParams, free: np.ndarray) -> np.ndarray:
    """Steady mean wind (…, rows) of each row, every turbine at rated reference, for free-stream speeds ``free``:
    one per case (…,), or one per row (…, rows) when each row sees its own (delayed) free stream.

    Rows are resolved front to back: row i's C_T follows from its own (waked) wind through the steady power curve
    and the actuator disc. Used for the initial state and for the delta-control demand.
    """
    free = np.asarray(free, dtype=float)
    n_rows = len(plant.rows())
    per_row = free if free.ndim and free.shape[-1] == n_rows and free.ndim > 1 else None
    curve = static_power_curve(params)
    distances = plant.row_distances_m()
    area_power = 0.5 * params.rho * math.pi * params.radius**2
    winds, cts = [], []
    for j, dj in enumerate(distances):
        free_j = free if per_row is None else per_row[..., j]
        if plant.wakes and j:
            deficits = [
                jensen_deficit(cts[i], dj - distances[i], params.radius, plant.wake_expansion) for i in range(j)
            ]
            v = free_j * (1.0 - np.sqrt(np.sum(np.square(deficits), axis=0)))
        else:
            v = free_j
        p_mech = np.interp(v, CURVE_WINDS, curve) / (params.eta_gc * params.eta_dt)
        cts.append(thrust_from_power_coefficient(p_mech / (area_power * np.maximum(v, 1.0) ** 3)))
        winds.append(v)
    return np.stack(winds, axis=-1)


def farm_available_power(plant: FarmPlant, params: TurbineParams, free: np.ndarray) -> np.ndarray:
    """Steady available power (W) of the farm for free-stream speeds ``free``: Σ_t P(v_row(t)), static wakes."""
    v = static_row_winds(plant, params, free)
    per_row = np.interp(v, CURVE_WINDS, static_power_curve(params))
    sizes = np.array([len(r) for r in plant.rows()])
    return per_row @ sizes


# ---- the free stream at the mast --------------------------------------------------------------------------------
class MastSeries:
    """The free stream at the mast of each run, sampled every FARM_DT_S from −HISTORY_S to the run's end.

    ``v[r, i]`` is the true mast wind of run r at t_i = i·FARM_DT_S − HISTORY_S, ``vbar`` its H(s) = 1/(s + 1)
    mean (eq. (3)). Both are exogenous (independent of the turbines), so they are drawn once.
    """

    def __init__(
        self, plant: FarmPlant, spec: WindSpec, rngs: Sequence[np.random.Generator], duration_s: float
    ) -> None:
        dt = FARM_DT_S
        self.offset = round(HISTORY_S / dt)  # index of t = 0
        n = self.offset + math.ceil(duration_s / dt) + 2
        self.t = np.arange(n) * dt - HISTORY_S
        vm = mean_wind(spec, np.maximum(self.t, 0.0))
        phi = math.exp(-dt / plant.coherent_time_s)
        z = np.empty((len(rngs), n))
        for r, rng in enumerate(rngs):
            w = rng.standard_normal(n)
            w[0] /= math.sqrt(1.0 - phi * phi)  # z(−HISTORY_S) drawn from the stationary distribution
            z[r] = signal.lfilter([math.sqrt(1.0 - phi * phi)], [1.0, -phi], w)  # z_k = φ z_{k−1} + √(1−φ²) w_k
        self.v = np.maximum(vm * (1.0 + plant.coherent_ti * z), 0.5)
        # H(s) = 1/(s + 1) by exact discretisation (zoh) at FARM_DT_S, started at its steady state.
        a = math.exp(-dt / MEAN_FILTER_S)
        zi = self.v[:, :1] * a
        self.vbar, _ = signal.lfilter([1.0 - a], [1.0, -a], self.v, axis=1, zi=zi)

    def at(self, runs: np.ndarray, t: np.ndarray) -> np.ndarray:
        """True mast wind of runs ``runs`` at times ``t`` (same shape), linear interpolation, m/s."""
        x = (t + HISTORY_S) / FARM_DT_S
        i = np.clip(x.astype(np.intp), 0, self.v.shape[1] - 2)
        frac = np.clip(x - i, 0.0, 1.0)
        return self.v[runs, i] * (1.0 - frac) + self.v[runs, i + 1] * frac


# ---- the wakes: the row model here, FLORIS's tables in plant_sim.farm.wakes ------------------------------------
class FarmWakes(Protocol):
    """What the field needs from a wake model, for a batch of farms of N turbines."""

    mast_distances: np.ndarray  # m, from the mast along the wind, of each point whose free stream is delayed
    initial_power: np.ndarray  # (farms, N) W, each turbine's steady aerodynamic power at t = 0

    @property
    def turbine_wind(self) -> np.ndarray: ...  # (farms, N) m/s, each turbine's mean wind at the last farm sample

    @property
    def free_wind(self) -> np.ndarray: ...  # (farms, N) m/s, the free stream it sees there

    def advance(
        self, j: int, p_aero: np.ndarray, area_power: float | np.ndarray, tsr: np.ndarray, pitch_deg: np.ndarray
    ) -> None: ...

    def available_power(self, params: TurbineParams, free: np.ndarray, held: np.ndarray) -> np.ndarray: ...

    @property
    def turbine_direction(self) -> np.ndarray: ...  # (farms, N) deg, unwrapped: the direction each turbine sees

    def free_stream_series(self, samples: int) -> np.ndarray | None:
        """(runs, samples, N) m/s, each turbine's free stream along a moving direction over the first ``samples``
        farm samples; None when the direction is fixed (the free stream is then eq. (3)'s delayed mast)."""
        ...


# ---- the row model's wakes -------------------------------------------------------------------------------------
class RowWakes:
    """The row model (module docstring) for a batch of farms: each row's delayed free stream and Jensen wakes.

    ``advance(j, p_aero, area_power)`` records each turbine's C_T at farm sample j and moves the row means to
    sample j + 1; ``turbine_wind`` / ``free_wind`` are each turbine's (farms, N) at the last sample.
    """

    def __init__(self, plant: FarmPlant, params: TurbineParams, mast: MastSeries, run_of_farm: np.ndarray) -> None:
        self.plant = plant
        self.mast = mast
        self.run_of_farm = np.asarray(run_of_farm)
        self.farms = len(self.run_of_farm)
        self.n_turbines = plant.n_turbines
        rows = plant.rows()
        self.row_of_turbine = np.array(plant.row_of())
        self.n_rows = len(rows)
        self.row_sizes = np.array([len(r) for r in rows], dtype=float)
        self.distances = np.array(plant.row_distances_m())
        self.mast_distances = plant.mast_distance_m + self.distances  # m, d_j of eq. (3)
        # upstream pairs (i, j): row i waking row j, with their distance x_ij
        pairs = [(i, j) for j in range(self.n_rows) for i in range(j)] if plant.wakes else []
        self._up = np.array([i for i, _ in pairs], dtype=np.intp)
        self._down = np.array([j for _, j in pairs], dtype=np.intp)
        self._x = np.array([self.distances[j] - self.distances[i] for i, j in pairs])
        self._pair_gain = (params.radius / (params.radius + plant.wake_expansion * self._x)) ** 2
        self._pair_to_row = np.zeros((len(pairs), self.n_rows))  # Σ over the upstream rows of each row
        self._pair_to_row[np.arange(len(pairs)), self._down] = 1.0
        self._row_matrix = np.zeros((self.n_turbines, self.n_rows))  # turbine → row mean
        for t in range(self.n_turbines):
            self._row_matrix[t, self.row_of_turbine[t]] = 1.0 / self.row_sizes[self.row_of_turbine[t]]
        area_power = 0.5 * params.rho * math.pi * params.radius**2
        # C_T history per (farm, row), one entry per farm sample, ring buffer long enough for the longest delay
        self._history = round(HISTORY_S / FARM_DT_S)
        free0 = mast.v[self.run_of_farm, mast.offset]
        v_rows0 = static_row_winds(plant, params, free0)  # (farms, rows)
        p_mech0 = np.interp(v_rows0, CURVE_WINDS, static_power_curve(params)) / (params.eta_gc * params.eta_dt)
        ct0 = thrust_from_power_coefficient(p_mech0 / (area_power * v_rows0**3))
        self._ct = np.repeat(ct0[:, :, None], self._history, axis=2)  # (farms, rows, history)
        self.initial_power = p_mech0[:, self.row_of_turbine]  # (farms, N) W, steady τ_r ω_r
        self.row_wind = v_rows0  # (farms, rows) m/s, mean wind of each row at the last farm sample
        self.row_free = free0[:, None].repeat(self.n_rows, axis=1)

    @property
    def turbine_direction(self) -> np.ndarray:
        """(farms, N) deg: the farm's fixed direction at every turbine (the row model's directions do not move)."""
        return np.full((self.farms, self.n_turbines), self.plant.direction_deg)

    def free_stream_series(self, samples: int) -> None:
        """None: the row model knows the paper's fixed directions only (``FarmWakes.free_stream_series``)."""
        return None

    @property
    def turbine_wind(self) -> np.ndarray:
        """(farms, N) m/s: each turbine's mean wind (its row's) at the last farm sample."""
        return self.row_wind[:, self.row_of_turbine]

    @property
    def free_wind(self) -> np.ndarray:
        """(farms, N) m/s: the free stream each turbine's row sees (delayed mast wind) at the last farm sample."""
        return self.row_free[:, self.row_of_turbine]

    def row_means(self, j: int, ct_rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(free stream, waked mean) of every row at farm sample j (t = j·FARM_DT_S), each (farms, rows), m/s."""
        t = j * FARM_DT_S
        runs = self.run_of_farm
        vbar = np.maximum(self.mast.vbar[runs, self.mast.offset + j], MIN_MEAN_WIND)  # (farms,)
        delays = np.minimum(self.mast_distances[None, :] / vbar[:, None], HISTORY_S)  # d_j / v̄, eq. (3)
        free = self.mast.at(np.broadcast_to(runs[:, None], delays.shape), t - delays)
        if len(self._up) == 0:
            return free, free
        lag = np.minimum(np.rint(self._x[None, :] / vbar[:, None] / FARM_DT_S).astype(np.intp), self._history - 1)
        slot = (j - lag) % self._history  # (farms, pairs)
        farms = np.arange(self.farms)[:, None]
        ct = ct_rows[farms, self._up[None, :], slot]
        deficit = (1.0 - np.sqrt(1.0 - np.clip(ct, 0.0, 1.0))) * self._pair_gain  # δ_ij, Jensen
        total = (deficit * deficit) @ self._pair_to_row  # Σ_i δ_ij² per row j
        return free, free * (1.0 - np.sqrt(total))

    def advance(
        self, j: int, p_aero: np.ndarray, area_power: float | np.ndarray, tsr: np.ndarray, pitch_deg: np.ndarray
    ) -> None:
        """Record each row's mean C_T (momentum theory on each turbine's C_p) at sample j; move to sample j + 1.

        ``tsr`` and ``pitch_deg`` (each turbine's operating point) are not used by the row model."""
        v_turbine = self.row_wind[:, self.row_of_turbine].reshape(-1)
        ct = thrust_from_power_coefficient(p_aero / (area_power * np.maximum(v_turbine, 1.0) ** 3))
        ct_rows = ct.reshape(self.farms, self.n_turbines) @ self._row_matrix  # (farms, rows) row means
        self._ct[:, :, j % self._history] = ct_rows
        self.row_free, self.row_wind = self.row_means(j + 1, self._ct)

    def available_power(self, params: TurbineParams, free: np.ndarray, held: np.ndarray) -> np.ndarray:
        """Steady available power (W), static wakes, for free streams ``free[:, held]`` (runs, samples, rows)."""
        v_rows = static_row_winds(self.plant, params, free[:, held, :])
        per_row = np.interp(v_rows, CURVE_WINDS, static_power_curve(params))
        return per_row @ self.row_sizes


# ---- the field the turbines sample ----------------------------------------------------------------------------
class FarmWindField(WindField):
    """Per-tick wind of n turbine rows (farms × N): each turbine's own turbulence on its delayed, waked mean.

    ``farm_of_row``/``turbine_of_row`` say which farm (index into ``run_of_farm``) and turbine each row is. The
    mean winds come from ``wakes`` (``RowWakes``, the default, or ``plant_sim.farm.wakes.TableWakes``).
    ``update(j, aero_power)`` is called by the plant on every farm sample j (t = j·FARM_DT_S) with each row's
    aerodynamic power τ_r ω_r (W); it advances the wakes and sets the turbines' means for the next FARM_DT_S.
    """

    def __init__(
        self,
        plant: FarmPlant,
        spec: WindSpec,
        params: TurbineParams,
        rngs: Sequence[np.random.Generator],
        mast: MastSeries,
        run_of_farm: np.ndarray,
        dt: float,
        row_rngs: Sequence[np.random.Generator] | None = None,
        wakes: FarmWakes | None = None,
        backend: str | None = None,
    ) -> None:
        super().__init__(spec, params, rngs, dt, backend=backend)
        # ``"numba"``: ``sample`` by ``plant_sim.farm.fast.blade_winds`` (the same numbers)
        self._farm_fast = fast_module("plant_sim.farm.fast") if self._fast is not None else None
        self._chunk_fast = self._farm_fast  # each turbulence chunk to its ticks in one kernel (the same numbers)
        self.plant = plant
        self.params = params
        self.mast = mast
        self.run_of_farm = np.asarray(run_of_farm)
        self.farms = len(self.run_of_farm)
        n_turbines = plant.n_turbines
        if self.n != self.farms * n_turbines:
            raise ValueError(f"{self.n} rows are not {self.farms} farms of {n_turbines} turbines")
        self.wakes = wakes if wakes is not None else RowWakes(plant, params, mast, run_of_farm)
        self.ticks_per_sample = round(FARM_DT_S / dt)
        self.row_of_turbine = np.array(plant.row_of())
        self.n_rows = int(self.row_of_turbine.max()) + 1
        self._area_power = 0.5 * params.rho * math.pi * params.radius**2
        self._p_aero = self.wakes.initial_power.reshape(-1)  # (n,) low-passed τ_r ω_r
        self._a_ct = math.exp(-FARM_DT_S / CT_FILTER_S)
        self.sample_index = 0
        self.turbine_wind = self.wakes.turbine_wind  # (farms, N) m/s, mean wind of each turbine at the last sample
        self.free_wind = self.wakes.free_wind  # (farms, N) m/s, the free stream each turbine sees
        self._offset_now = self.turbine_wind.reshape(-1) - float(mean_wind(spec, 0.0))
        self._mean_knots = tuple(np.array(knots, dtype=float) for knots in zip(*spec.mean, strict=True))
        self._offset_step = np.zeros(self.n)
        self.rotor_wind = self.turbine_wind.reshape(-1)  # (n,) m/s, rotor-averaged wind of the last tick
        self.turbulence_gain = self._gain()  # (n,) TI_t / TI_0 of each turbine, None: the ambient's for all
        # Row-shared turbulence (``row_coherence`` c): each turbine's turbulence is √(1−c) its own + √c its row's,
        # the row's drawn from ``row_rngs`` (one per farm and row, farm-major), same spectrum and level.
        self.coherence = plant.row_coherence
        self._row_field: WindField | None = None
        if self.coherence > 0.0:
            if row_rngs is None or len(row_rngs) != self.farms * self.n_rows:
                raise ValueError("row_coherence > 0 needs one random stream per farm and row")
            self._row_field = WindField(spec, params, row_rngs, dt)
            farm_of = np.repeat(np.arange(self.farms), n_turbines)
            self._row_stream = farm_of * self.n_rows + np.tile(self.row_of_turbine, self.farms)

    @property
    def row_wind(self) -> np.ndarray:
        """The row model's (farms, rows) row means; with FLORIS wakes each turbine's own (farms, N)."""
        return getattr(self.wakes, "row_wind", self.turbine_wind)

    def _refill(self) -> None:
        super()._refill()
        rf = self._row_field
        if rf is None:
            return
        rf._refill()  # the same chunk of ticks: both fields use the same sample time and chunk length
        own, shared = math.sqrt(1.0 - self.coherence), math.sqrt(self.coherence)
        idx = self._row_stream
        vm = self._mean
        self._hub = vm + own * (self._hub - vm) + shared * (rf._hub[:, idx] - rf._mean[:, idx])
        self._base = vm + own * (self._base - vm) + shared * (rf._base[:, idx] - rf._mean[:, idx])
        self._u3 = own * self._u3 + shared * rf._u3[:, idx]

    def set_air_density(self, rho: np.ndarray) -> None:
        """Each turbine's own air density (n,) kg/m³: its C_T is read from its aerodynamic power against ½ρπR²v³."""
        self._area_power = 0.5 * np.asarray(rho, dtype=float) * math.pi * self.params.radius**2

    # -- the farm sample --------------------------------------------------------------------------------------
    def update(self, j: int, aero_power: np.ndarray, omega_r: np.ndarray, pitch_deg: np.ndarray) -> None:
        """Farm sample j: pass each turbine's operating point to the wakes, then set its mean for ticks j·S … (j+1)·S.

        ``aero_power`` τ_r ω_r (W), ``omega_r`` (rad/s) and ``pitch_deg`` (collective, deg) of each turbine; its
        tip-speed ratio is read against the rotor-averaged wind it saw on the last tick."""
        self._p_aero = self._a_ct * self._p_aero + (1.0 - self._a_ct) * aero_power
        tsr = omega_r * self.params.radius / np.maximum(self.rotor_wind, 1.0)
        self.wakes.advance(j, self._p_aero, self._area_power, tsr, pitch_deg)
        mean_next = self.wakes.turbine_wind
        target = mean_next.reshape(-1) - float(np.interp((j + 1) * FARM_DT_S, *self._mean_knots))  # ``mean_wind``
        start = self._offset_now + self._offset_step * self.ticks_per_sample
        self._offset_now = start
        self._offset_step = (target - start) / self.ticks_per_sample
        self.turbine_wind, self.free_wind = mean_next, self.wakes.free_wind
        self.turbulence_gain = self._gain()
        self.sample_index = j + 1

    def _gain(self) -> np.ndarray | None:
        """Each turbine's turbulence over the ambient (wake-added turbulence), from wakes that compute it."""
        ratio = getattr(self.wakes, "turbulence_ratio", None)
        return None if ratio is None else ratio.reshape(-1)

    # -- per tick -------------------------------------------------------------------------------------------------
    def sample(self, k: int, azimuth: np.ndarray) -> WindSample:
        """Wind at tick k for blade-1 azimuth ``azimuth`` (n,) rad: the base field's turbulence on the row means."""
        if k != self._next_k:
            raise ValueError(f"FarmWindField.sample expects tick {self._next_k}, got {k}")
        self._next_k = k + 1
        if k >= self._chunk_end:
            self._refill()
        j = k - self._chunk_start
        if self._farm_fast is not None:
            return self._fast_sample(j, k, azimuth)
        offset = self._offset_now + self._offset_step * (k % self.ticks_per_sample)  # v_row − v_m, interpolated
        x = np.mod(azimuth, 2.0 * math.pi)[:, None] * self._per_rad + self._offsets
        i = x.astype(np.intp)
        f = self._table[i] + self._slope[i] * (x - i)  # F(ψ_i)
        base, hub, u3 = self._base[j], self._hub[j], self._u3[j]
        if self.turbulence_gain is not None:  # each turbine's turbulence σ × TI_t / TI_0 (the wake-added part)
            g, vm = self.turbulence_gain, self._mean[j]
            base, hub, u3 = vm + g * (base - vm), vm + g * (hub - vm), g * u3
        w = (base + offset) + u3 * np.cos(3.0 * azimuth)  # w = v_row + u_0 + u_3 cos 3ψ
        blades = w[:, None] * f
        rotor = blades @ _THIRDS  # mean of the three blades
        self.rotor_wind = rotor
        mean = self._mean[j] + offset
        return WindSample(blades=blades, hub=hub + offset, rotor=rotor, mean=mean)

    def _fast_sample(self, j: int, k: int, azimuth: np.ndarray) -> WindSample:
        """``sample``'s arithmetic by ``plant_sim.farm.fast.blade_winds``; the blades' mean by the same product."""
        n = self.n
        blades, hub, mean = np.empty((n, 3)), np.empty(n), np.empty(n)
        fields = (self._base[j], self._hub[j], self._u3[j], self._mean[j])
        drift = (self._offset_now, self._offset_step, float(k % self.ticks_per_sample))
        azimuth = np.ascontiguousarray(azimuth, dtype=float)
        args = (self._table, self._slope, self._per_rad, self._offsets, fields, self.turbulence_gain, drift)
        self._farm_fast.blade_winds(azimuth, *args, blades, hub, mean)
        self.rotor_wind = rotor = blades @ _THIRDS
        return WindSample(blades=blades, hub=hub, rotor=rotor, mean=mean)
