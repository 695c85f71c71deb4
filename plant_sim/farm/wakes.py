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

**A moving direction** (``plant_sim.farm.direction``): the free streams, the pair distances and the tables'
direction are those of the run's direction at each sample, and the steady states (t = 0, the demand's updates)
are taken at the direction of their sample.
"""

from __future__ import annotations

import importlib
import math
from pathlib import Path

import numpy as np

from plant_sim.farm.direction import DirectionSeries, advected_distance, downwind_distances, lookup_times
from plant_sim.farm.operating_curve import rated_curve
from plant_sim.farm.wake_tables import WakeTables
from plant_sim.farm.wind import CT_FILTER_S, HISTORY_S, MIN_MEAN_WIND, MastSeries
from wwcore import thrust
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
    # Imported here, not at the top: FLORIS takes seconds to import and only farms with FLORIS wakes need it (every
    # farm scenario imports this module). There is no import cycle to dodge: floris_wakes does not import this module.
    floris_wakes = importlib.import_module("plant_sim.farm.floris_wakes")
    lo, hi = plant.direction_sector_deg()  # the direction, or the range a moving one reaches
    lo, hi = lo - SECTOR_HALF_WIDTH_DEG, hi + SECTOR_HALF_WIDTH_DEG
    settings = floris_wakes.WakeSettings(
        model=plant.wake_model,
        turbulence_intensity=max(wind.turbulence_intensity, MIN_WAKE_TI),
        sector_deg=(lo, hi) if hi - lo < 360.0 else None,
    )
    return floris_wakes.wake_tables(plant.resolved_layout(), settings, params, cache_dir)


def steady_winds(
    tables: WakeTables | None, direction_deg: float | np.ndarray, free: np.ndarray, params: TurbineParams
) -> tuple[np.ndarray, np.ndarray]:
    """(speed, C_T), each (B, N), of B farms in steady state on the rated curve, for free streams ``free`` (B, N)
    and wind from ``direction_deg`` (one for all, or (B,) each farm's).

    Wakes run downstream only, so the sweeps reach the fixed point after the longest chain of turbines in each
    other's wake (at most N + 1 sweeps).
    """
    winds, _, ct_curve = rated_curve(params)
    free = np.asarray(free, dtype=float)
    speed = free.copy()
    if tables is not None:
        directions = np.broadcast_to(np.asarray(direction_deg, dtype=float), free.shape[:1])
        for _ in range(free.shape[1] + 1):
            new = tables.waked(directions, np.interp(speed, winds, ct_curve), free)[0]
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
        self.direction = direction if direction is not None and direction.varies else None
        if self.direction is not None:  # a moving direction: the geometry at every sample (plant_sim.farm.direction)
            self._layout = layout
            self._directions = self.direction.at(self.run_of_farm, 0)
            s0 = downwind_distances(layout, self._directions)  # (farms, N)
            self._advected = advected_distance(mast.vbar)  # (runs, samples) X of each run's mast series
            self._lookup = self._lookup_times(0, plant.mast_distance_m + s0, None)
            v0, ct0 = steady_winds(self.tables, self._directions, free0, params)
            self.initial_power = np.interp(v0, winds, power) / (params.eta_gc * params.eta_dt)
            self._ct[:] = ct0[:, :, None].astype(np.float32)
            self._ct_filtered = ct0
        self._mast_distance = plant.mast_distance_m
        self.turbine_wind = v0
        self.free_wind = free0
        self.turbulence_ratio: np.ndarray | None = None  # (farms, N) TI_t / TI_0; None: ambient everywhere
        self._added_turbulence = plant.wake_added_turbulence and self.tables is not None
        if self._added_turbulence:
            self._set_turbulence(self.tables.waked(self._directions, ct0, free0)[1])

    def advance(
        self, j: int, p_aero: np.ndarray, area_power: float | np.ndarray, tsr: np.ndarray, pitch_deg: np.ndarray
    ) -> None:
        """Record each turbine's C_T at farm sample j (from ``tsr`` and ``pitch_deg``, (n,), low-passed; ``p_aero``
        and ``area_power`` are the row model's inputs, not used); set the free streams and winds of sample j + 1."""
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
        else:  # along the direction of this sample (plant_sim.farm.direction)
            self._directions = self.direction.at(runs, nxt)
            s = downwind_distances(self._layout, self._directions)  # (farms, N)
            self._lookup = self._lookup_times(nxt, self._mast_distance + s, self._lookup)
            free = self.mast.at(np.broadcast_to(runs[:, None], s.shape), self._lookup)
            x = np.maximum(s[:, None, :] - s[:, :, None], 0.0)  # (farms, N, N) x_ij
        if self.tables is None:
            self.free_wind, self.turbine_wind = free, free
            return
        lag = np.rint(x / (vbar[:, None, None] * FARM_DT_S)).astype(np.intp)
        lag = np.clip(lag, 1, self._history - 1)  # the newest C_T is sample j's
        slot = (nxt - lag) % self._history  # (farms, N, N): when the wake now at j left i
        pair_thrust = self._ct[self._farm, self._source, slot]
        self.turbine_wind, turbulence = self.tables.waked(self._directions, pair_thrust, free)
        self.free_wind = free
        if self._added_turbulence:
            self._set_turbulence(turbulence)

    def free_stream_series(self, samples: int) -> np.ndarray | None:
        """The free stream (m/s) each turbine of each run sees at farm samples 0 … samples − 1, (runs, samples, N),
        along the moving direction with the same lookup times as ``advance``; None when the direction is fixed."""
        if self.direction is None:
            return None
        runs = self.mast.v.shape[0]
        span = slice(self.direction.offset, self.direction.offset + samples)
        d = self._mast_distance + downwind_distances(self._layout, self.direction.deg[:, span])  # (runs, samples, N)
        x_now = self._advected[:, self.mast.offset : self.mast.offset + samples, None]
        tau = np.stack([np.interp(x_now[r] - d[r], self._advected[r], self.mast.t) for r in range(runs)])
        tau = np.maximum.accumulate(tau, axis=1)
        return self.mast.at(np.broadcast_to(np.arange(runs)[:, None, None], tau.shape), tau)

    def _lookup_times(self, j: int, distances: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
        """τ (farms, N) at farm sample j for points ``distances`` (farms, N) m from the mast (``lookup_times``)."""
        out = np.empty_like(distances)
        for f, r in enumerate(self.run_of_farm):
            x = self._advected[r]
            out[f] = lookup_times(x[self.mast.offset + j], distances[f], x, self.mast.t, None)
        return out if previous is None else np.maximum(out, previous)

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
        if self.direction is not None:  # each run's direction at each update
            direction = self.direction.deg[:runs, self.direction.offset + distinct].reshape(-1)
        speed, _ = steady_winds(self.tables, direction, free[:, distinct, :].reshape(-1, n), params)
        winds, power, _ = rated_curve(params)
        total = np.interp(speed, winds, power).sum(axis=1).reshape(runs, len(distinct))
        return total[:, which.reshape(-1)]
