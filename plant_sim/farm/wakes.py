r"""FLORIS's wakes in the farm plant: per-turbine free streams, delayed per-pair thrust, steady states.

With ``wake_model = "gauss"`` or ``"jensen"`` the farm's mean winds come from the wake tables of
``plant_sim.farm.floris_wakes`` (built once at scenario start for the farm's layout and wind direction, cached on
disk) instead of the row model of ``plant_sim.farm.wind``. At every farm sample j (10 Hz; the 100 Hz loop only
interpolates between samples and never sees FLORIS):

* **Free stream of each turbine.** Turbine t, s_t metres downwind of the most upwind turbine and d_t = d_mast + s_t
  from the mast along the wind direction θ, sees the mast wind delayed by d_t / v̄ (seed 001 eq. (3), per turbine
  instead of per row): U_t(t) = v_mast(t − d_t / v̄).
* **Thrust.** Each turbine's C_T comes from its own operating point: ``wwcore.thrust.thrust_coefficient`` at its
  tip-speed ratio λ = ω_r R / v_rotor (v_rotor the rotor-averaged wind of its last tick) and collective pitch β,
  low-passed over ``CT_FILTER_S`` (the loss-corrected actuator disc: C_T ≈ 0.75 below rated for the benchmark
  rotor; the same function defines the steady curve FLORIS's turbine follows). A derated turbine, pitched and
  slowed, casts a weaker wake. Reading C_T from C_p = τ_r ω_r / (½ρπR²v³) against the *mean* wind instead (as the
  row model does) biases it by the turbine's own turbulence: 0.47–0.85 between turbines at 8 m/s, TI 0.10.
* **Travel delay.** The wake of i reaches j, x_ij = s_j − s_i downstream, a time x_ij / v̄ after it left i, so the
  pair uses C_T,i of that many samples before (``FarmLayout.along_wind_matrix``; at least one sample).
* **Combination.** ``WakeTables.waked`` with each pair's delayed C_T and each turbine's free stream, as FLORIS's
  sequential solver combines (sum of squares of the rotor-averaged deficits, wake-added turbulence).
* **Wake-added turbulence** (``wake_added_turbulence``, default on): each turbine's own turbulence (Kaimal, the
  scenario's TI_0 of the free stream) is scaled by TI_t / TI_0, TI_t the turbulence intensity FLORIS gives it
  (ambient and the largest wake-added part, Crespo–Hernández), as IEC 61400-1's effective turbulence raises σ in a
  wake; the spectrum keeps the ambient shape (a wake's own eddies are smaller, about a rotor diameter).

The steady state (t = 0, and the delta-control demand's available power) puts each turbine on the benchmark's
steady operating curve (``operating_curve.rated_curve``, the curve the FLORIS turbine is defined by) and sweeps the
tables until the winds stop changing. The ambient turbulence intensity of the tables is the scenario's
``wind.turbulence_intensity`` (at least ``MIN_WAKE_TI``); the tables cover ``SECTOR_HALF_WIDTH_DEG`` either side
of the directions a run can reach (``FarmPlant.direction_sector_deg``: the constant direction, or a moving one's
range with its veer bound).

**A moving direction** (``plant_sim.farm.direction``): the direction is carried across the farm with the wind.
Each turbine sees the newest air that has reached it, τ_t, computed once per run: its free stream is v_mast(τ_t)
and its direction θ_t = θ(τ_t); the pairs reaching j are looked up at θ_j with x_ij along θ_j
(``WakeTables.waked_per_turbine``); the steady states (t = 0, the demand's updates) are taken with each turbine's
direction of their sample.
"""

from __future__ import annotations

import importlib
import math
from pathlib import Path

import numpy as np

from plant_sim.farm.direction import DirectionSeries, advected_distance, arrival_lookup
from plant_sim.farm.operating_curve import rated_curve
from plant_sim.farm.wake_cache import WakeSettings, cached_wake_tables
from plant_sim.farm.wake_tables import WakeTables
from plant_sim.farm.wind import CT_FILTER_S, HISTORY_S, MIN_MEAN_WIND, MastSeries
from wwcore import thrust
from wwcore.backend import fast_module, resolve_backend
from wwcore.scenario.farm import FARM_DT_S, FarmPlant
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_params import TurbineParams

MIN_WAKE_TI = 0.02  # –, floor of the ambient turbulence intensity the wake tables are built for
SECTOR_HALF_WIDTH_DEG = 5.0  # deg, the tables cover the wind direction ± this


def plant_wake_tables(
    plant: FarmPlant, wind: WindSpec, params: TurbineParams, cache_dir: Path | str | None = None
) -> WakeTables:
    """The farm's FLORIS wake tables for its layout, wake model, wind direction and turbulence intensity.

    Built by FLORIS on first use and cached (``cache_dir``, default ``$WINDWARDEN_CACHE/wakes`` or
    ``~/.cache/windwarden/wakes``): a second start with the same farm and settings loads them in milliseconds.
    """
    if plant.wake_model not in ("gauss", "jensen"):
        raise ValueError(f"wake_model {plant.wake_model!r} has no FLORIS tables; use 'gauss' or 'jensen'")
    lo, hi = plant.direction_sector_deg()  # the direction, or the range a moving one reaches
    lo, hi = lo - SECTOR_HALF_WIDTH_DEG, hi + SECTOR_HALF_WIDTH_DEG
    settings = WakeSettings(
        model=plant.wake_model,
        turbulence_intensity=max(wind.turbulence_intensity, MIN_WAKE_TI),
        sector_deg=(lo, hi) if hi - lo < 360.0 else None,
    )
    layout = plant.resolved_layout()
    _, _, tables = cached_wake_tables(layout, settings, params, cache_dir)
    if tables is not None:
        return tables
    # Imported only to build the tables: FLORIS takes seconds to import, and a cached table does not need it (every
    # process of an evaluation loads one). There is no import cycle to dodge: floris_wakes does not import this module.
    floris_wakes = importlib.import_module("plant_sim.farm.floris_wakes")
    return floris_wakes.wake_tables(layout, settings, params, cache_dir)


def steady_winds(
    tables: WakeTables | None, direction_deg: float | np.ndarray, free: np.ndarray, params: TurbineParams
) -> tuple[np.ndarray, np.ndarray]:
    """(speed, C_T), each (B, N), of B farms in steady state on the rated curve, for free streams ``free`` (B, N)
    and wind from ``direction_deg`` (one for all, (B,) each farm's, or (B, N) each turbine's).

    Wakes run downstream only, so the sweeps reach the fixed point after the longest chain of turbines in each
    other's wake (at most N + 1 sweeps).
    """
    winds, _, ct_curve = rated_curve(params)
    free = np.asarray(free, dtype=float)
    speed = free.copy()
    if tables is not None:
        per_turbine = np.ndim(direction_deg) == 2
        directions = np.asarray(direction_deg, dtype=float)
        waked = tables.waked_per_turbine if per_turbine else tables.waked
        if not per_turbine:
            directions = np.broadcast_to(directions, free.shape[:1])
        for _ in range(free.shape[1] + 1):
            new = waked(directions, np.interp(speed, winds, ct_curve), free)[0]
            if np.array_equal(new, speed):
                break
            speed = new
    return speed, np.interp(speed, winds, ct_curve)


class TableWakes:
    """FLORIS's wakes for a batch of farms (module docstring); the ``FarmWakes`` interface of the farm field."""

    def __init__(
        self,
        plant: FarmPlant,
        params: TurbineParams,
        tables: WakeTables | None,
        mast: MastSeries,
        run_of_farm: np.ndarray,
        direction: DirectionSeries | None = None,
        backend: str | None = None,
    ) -> None:
        if tables is not None and tables.n_turbines != plant.n_turbines:
            raise ValueError(f"wake tables for {tables.n_turbines} turbines, the farm has {plant.n_turbines}")
        self.params = params
        self.tables = tables if plant.wakes else None
        self.mast = mast
        self.run_of_farm = np.asarray(run_of_farm)
        self.farms = len(self.run_of_farm)
        self.n_turbines = n = plant.n_turbines
        self.direction_deg = plant.direction_deg
        layout = plant.resolved_layout()
        self.mast_distances = plant.mast_distance_m + layout.wind_frame(self.direction_deg).downwind  # (N,) m
        self._x = np.maximum(layout.along_wind_matrix(self.direction_deg), 0.0)  # (N, N) m, x_ij downstream
        self._history = round(HISTORY_S / FARM_DT_S)
        free0 = np.repeat(mast.v[self.run_of_farm, mast.offset][:, None], n, axis=1)  # (farms, N)
        v0, ct0 = steady_winds(self.tables, self.direction_deg, free0, params)
        winds, power, _ = rated_curve(params)
        self.initial_power = np.interp(v0, winds, power) / (params.eta_gc * params.eta_dt)
        # C_T per (farm, turbine) at each farm sample, a ring buffer as long as the longest travel delay
        self._ct = np.repeat(ct0[:, :, None].astype(np.float32), self._history, axis=2)
        self._ct_filtered = ct0
        self._a_ct = math.exp(-FARM_DT_S / CT_FILTER_S)
        self._farm = np.arange(self.farms)[:, None, None]
        self._source = np.arange(n)[None, :, None]
        self._directions = np.full(self.farms, self.direction_deg)
        self.turbine_direction = np.full((self.farms, n), self.direction_deg)  # (farms, N) deg, θ_t of each
        self.direction = direction if direction is not None and direction.varies else None
        if self.direction is not None:  # carried with the wind (plant_sim.farm.direction)
            self._layout = layout
            self._tau = self._arrival_times(plant.mast_distance_m)  # (runs, samples, N) s, τ_t at each sample
            self.turbine_direction = self._directions_at(0)
            self._directions = self.turbine_direction
            free0 = self.mast.at(np.broadcast_to(self.run_of_farm[:, None], (self.farms, n)), self.lookup)
            v0, ct0 = steady_winds(self.tables, self._directions, free0, params)
            self.initial_power = np.interp(v0, winds, power) / (params.eta_gc * params.eta_dt)
            self._ct[:] = ct0[:, :, None].astype(np.float32)
            self._ct_filtered = ct0
        self.turbine_wind = v0
        self.free_wind = free0
        self.turbulence_ratio: np.ndarray | None = None  # (farms, N) TI_t / TI_0; None: ambient everywhere
        self._added_turbulence = plant.wake_added_turbulence and self.tables is not None
        if self._added_turbulence:
            self._set_turbulence(self._waked(ct0, free0)[1])
        # ``"numba"`` at a fixed direction with tables: ``advance`` after the C_T by ``plant_sim.farm.fast.wake_step``
        # (the same numbers); the table interval of the direction and its entries are the same at every sample
        self._fast = None
        if resolve_backend(backend) == "numba" and self.tables is not None and self.direction is None:
            self._fast = fast_module("plant_sim.farm.fast")
            t = self.tables
            x = (self.direction_deg % 360.0) / t.direction_step_deg
            self._fast_entries = t._bin(math.floor(x) % t.n_directions)
            self._fast_weight = np.full(self.farms, x - math.floor(x))
            self._fast_tables = (
                t.added_ti.reshape(-1),
                t.deficit.reshape(-1),
                np.asarray(t.ti_grid, dtype=float),
                t._ct_max,
                t._inv_s_step,
                t._m_last,
                t._inv_ti_step,
                t.ambient_ti**2,
            )
            self._ct_filtered = np.array(self._ct_filtered, dtype=float)
            m = self.mast
            self._fast_mast = (m.vbar, m.offset, m.v, self.run_of_farm, self.mast_distances, MIN_MEAN_WIND)
            self._fast_mast += (FARM_DT_S, HISTORY_S)
            self._x_contiguous = np.ascontiguousarray(self._x)

    def advance(
        self, j: int, p_aero: np.ndarray, area_power: float | np.ndarray, tsr: np.ndarray, pitch_deg: np.ndarray
    ) -> None:
        """Record each turbine's C_T at farm sample j (from ``tsr`` and ``pitch_deg``, (n,), low-passed; ``p_aero``
        and ``area_power`` are the row model's inputs, not used); set the free streams and winds of sample j + 1."""
        if self._fast is not None:  # the C_T by ``wwcore.thrust_fast`` (the same numbers)
            ct = self._fast.thrust_coefficient(tsr, pitch_deg).reshape(self.farms, self.n_turbines)
            self._fast_advance(j + 1, ct)
            return
        ct = thrust.thrust_coefficient(tsr, pitch_deg).reshape(self.farms, self.n_turbines)
        self._ct_filtered = self._a_ct * self._ct_filtered + (1.0 - self._a_ct) * ct
        self._ct[:, :, j % self._history] = self._ct_filtered
        nxt = j + 1
        runs = self.run_of_farm
        vbar = np.maximum(self.mast.vbar[runs, self.mast.offset + nxt], MIN_MEAN_WIND)  # (farms,)
        if self.direction is None:
            delays = np.minimum(self.mast_distances[None, :] / vbar[:, None], HISTORY_S)  # d_t / v̄, eq. (3)
            free = self.mast.at(np.broadcast_to(runs[:, None], delays.shape), nxt * FARM_DT_S - delays)
            x = self._x[None, :, :]
        else:  # the direction each turbine sees, carried with the wind (plant_sim.farm.direction)
            self._directions = self.turbine_direction = self._directions_at(nxt)
            free = self.mast.at(np.broadcast_to(runs[:, None], self._directions.shape), self._tau[runs, nxt])
            x = self._pair_distances(self._directions)
        if self.tables is None:
            self.free_wind, self.turbine_wind = free, free
            return
        lag = np.rint(x / (vbar[:, None, None] * FARM_DT_S)).astype(np.intp)
        lag = np.clip(lag, 1, self._history - 1)  # the newest C_T is sample j's
        slot = (nxt - lag) % self._history  # (farms, N, N): when the wake now at j left i
        pair_thrust = self._ct[self._farm, self._source, slot]
        self.turbine_wind, turbulence = self._waked(pair_thrust, free)
        self.free_wind = free
        if self._added_turbulence:
            self._set_turbulence(turbulence)

    def _fast_advance(self, nxt: int, ct: np.ndarray) -> None:
        """``advance``'s arithmetic after the C_T by ``plant_sim.farm.fast.wake_step``, into new arrays."""
        shape = (self.farms, self.n_turbines)
        free, speed, turbulence = np.empty(shape), np.empty(shape), np.empty(shape)
        args = (self._ct_filtered, self._ct, self._fast_mast, self._x_contiguous, self._fast_entries)
        self._fast.wake_step(ct, nxt, self._a_ct, *args, self._fast_weight, self._fast_tables, free, speed, turbulence)
        self.free_wind, self.turbine_wind = free, speed
        if self._added_turbulence:
            self._set_turbulence(turbulence)

    def free_stream_series(self, samples: int) -> np.ndarray | None:
        """The free stream (m/s) each turbine of each run sees at farm samples 0 … samples − 1, (runs, samples, N),
        with the same τ_t as ``advance``; None when the direction is fixed."""
        if self.direction is None:
            return None
        tau = self._tau[:, :samples]
        return self.mast.at(np.broadcast_to(np.arange(tau.shape[0])[:, None, None], tau.shape), tau)

    @property
    def lookup(self) -> np.ndarray | None:
        """τ_t (farms, N) s of the last farm sample: when the air each turbine sees passed the mast; None when the
        direction is fixed (eq. (3)'s t − d_t/v̄)."""
        return None if self.direction is None else self._tau[self.run_of_farm, self.sample]

    def _arrival_times(self, mast_distance_m: float) -> np.ndarray:
        """τ_t (runs, samples, N) at farm samples 0, 1, … of every run (``direction.arrival_lookup``)."""
        mast, direction = self.mast, self.direction
        samples = direction.deg.shape[1] - direction.offset
        query = np.arange(samples) * FARM_DT_S
        advected = advected_distance(mast.vbar)  # (runs, S) X of each run's mast series
        return np.stack(
            [
                arrival_lookup(mast.t, advected[r], direction.path_deg, self._layout, mast_distance_m, query)
                for r in range(mast.v.shape[0])
            ]
        )

    def _directions_at(self, j: int) -> np.ndarray:
        """θ_t (farms, N) deg, unwrapped: the direction the air each turbine sees at farm sample j carries; j becomes
        the sample ``lookup`` reads."""
        self.sample = j
        runs = self.run_of_farm
        return self.direction.at_time(np.broadcast_to(runs[:, None], (self.farms, self.n_turbines)), self._tau[runs, j])

    def _pair_distances(self, directions: np.ndarray) -> np.ndarray:
        """x_ij (farms, N, N) m ≥ 0: j's distance downstream of i along θ_j, the direction of the air at j."""
        th = np.radians(directions)[:, None, :]  # (farms, 1, N): column j's direction
        layout = self._layout
        along = -layout.x[None, :, None] * np.sin(th) - layout.y[None, :, None] * np.cos(th)  # [f, i, j]: i along θ_j
        return np.maximum(np.diagonal(along, axis1=1, axis2=2)[:, None, :] - along, 0.0)

    def _waked(self, thrust: np.ndarray, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``WakeTables.waked`` at each farm's direction, or ``waked_per_turbine`` at each turbine's."""
        if self.direction is None:
            return self.tables.waked(self._directions, thrust, free)
        return self.tables.waked_per_turbine(self._directions, thrust, free)

    def _set_turbulence(self, turbulence: np.ndarray) -> None:
        """Each turbine's turbulence intensity over the ambient, the factor on its own turbulence."""
        self.turbulence_ratio = turbulence * (1.0 / self.tables.ambient_ti)

    def available_power(self, params: TurbineParams, free: np.ndarray, held: np.ndarray) -> np.ndarray:
        """Steady available power (W) for free streams ``free[:, held]`` (runs, samples, N) on the rated curve.

        ``held`` repeats each update's sample (the demand holds its estimate), so each distinct one is solved once.
        """
        distinct, which = np.unique(held, return_inverse=True)
        runs, _, n = free.shape
        direction: float | np.ndarray = self.direction_deg
        if self.direction is not None:  # each turbine's direction at each update
            tau = self._tau[:runs, distinct]  # (runs, updates, N)
            direction = self.direction.at_time(np.broadcast_to(np.arange(runs)[:, None, None], tau.shape), tau)
            direction = direction.reshape(-1, n)
        speed, _ = steady_winds(self.tables, direction, free[:, distinct, :].reshape(-1, n), params)
        winds, power, _ = rated_curve(params)
        total = np.interp(speed, winds, power).sum(axis=1).reshape(runs, len(distinct))
        return total[:, which.reshape(-1)]
