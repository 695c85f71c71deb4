r"""Steady wake tables of a farm and their combination at the farm rate (pure numpy; built by ``floris_wakes``).

A table holds, for wind directions θ_k = k Δθ (k = 0 … 360/Δθ − 1) and every ordered pair (i, j) whose wake can
reach (i upstream), the rotor-averaged deficit fraction δ_ij(θ_k, C_T, TI) and the wake-added turbulence
τ_ij(θ_k, C_T) that FLORIS computes (``plant_sim.farm.floris_wakes``). Entries are stored by direction (CSR:
``bin_start[k]`` … ``bin_start[k+1]``), only where δ or τ reaches the build's ``min_deficit``.

**Combination** (``waked``), as FLORIS's sequential solver combines, for direction θ, each pair's thrust
coefficient C_T,ij (the C_T of i when the wake now at j left it, so the plant can delay it by x_ij / v̄ with
``FarmLayout.along_wind_matrix``) and each turbine's free stream U_j:

.. math::  \mathrm{TI}_j = \sqrt{\mathrm{TI}_0^2 + \max_i τ_{ij}(θ, C_{T,ij})^2}
           \qquad v_j = U_j \Bigl(1 - \sqrt{\textstyle\sum_i δ_{ij}(θ, C_{T,ij}, \mathrm{TI}_i)^2}\Bigr)

(FLORIS's crespo–hernández turbulence taken as the maximum over upstream turbines, and its default "sosfs"
sum-of-squares free-stream superposition, here on rotor-averaged deficits: within 0.003 m/s of FLORIS's
point-by-point sum in the tests). δ and τ are linear in θ between table directions, linear in s = 1 − √(1 − C_T)
(Jensen's deficit is exactly linear in s) and in TI; C_T is clipped to the table's range. Turbulence intensity
does not propagate with a delay (a second-order effect on the deficit's width).

Cost: one gather of the entries of the two table directions around θ, a bilinear interpolation, and two
``bincount`` scatters into dense (N, N) matrices; no Python loop over turbines or pairs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

FORMAT_VERSION = 1
_ARRAYS = ("bin_start", "upstream", "downstream", "thrust_grid", "ti_grid", "deficit", "added_ti", "covered")
_SCALARS = ("key", "model", "n_turbines", "direction_step_deg", "ambient_ti", "settings_json")


@dataclass(frozen=True)
class WakeTables:
    key: str
    model: str
    n_turbines: int
    direction_step_deg: float
    bin_start: np.ndarray  # (K + 1,) int64
    upstream: np.ndarray  # (E,) int32, i
    downstream: np.ndarray  # (E,) int32, j
    thrust_grid: np.ndarray  # (M,) C_T nodes, uniform in s = 1 − √(1 − C_T), first node 0
    ti_grid: np.ndarray  # (T,) TI nodes, uniform (T = 1 for Jensen)
    deficit: np.ndarray  # (E, M, T) float32, δ
    added_ti: np.ndarray  # (E, M) float32, τ
    ambient_ti: float
    covered: np.ndarray  # (K,) bool, the table directions that were computed (a sector, or all)
    settings_json: str = "{}"
    _cache: dict = field(init=False, repr=False, compare=False, default_factory=dict)
    _by_downstream: list = field(init=False, repr=False, compare=False, default_factory=list)

    def __post_init__(self) -> None:
        k = len(self.bin_start) - 1
        if not math.isclose(k * self.direction_step_deg, 360.0, abs_tol=1e-6):
            raise ValueError(f"{k} directions of {self.direction_step_deg} deg do not cover 360 deg")
        e = int(self.bin_start[-1])
        shapes_ok = (
            self.upstream.shape == (e,)
            and self.downstream.shape == (e,)
            and self.deficit.shape == (e, len(self.thrust_grid), len(self.ti_grid))
            and self.added_ti.shape == (e, len(self.thrust_grid))
        )
        if not shapes_ok or np.any(np.diff(self.bin_start) < 0):
            raise ValueError("wake table arrays are inconsistent")
        pairs = np.concatenate([self.upstream, self.downstream])
        if e and (pairs.min() < 0 or pairs.max() >= self.n_turbines):
            raise ValueError("wake table names a turbine outside the farm")
        s = 1.0 - np.sqrt(1.0 - self.thrust_grid)
        object.__setattr__(self, "_inv_s_step", 1.0 / float(s[1] - s[0]))
        object.__setattr__(self, "_ct_max", float(self.thrust_grid[-1]))
        object.__setattr__(self, "_m_last", len(self.thrust_grid) - 2)
        step = float(self.ti_grid[1] - self.ti_grid[0]) if len(self.ti_grid) > 1 else 1.0
        object.__setattr__(self, "_inv_ti_step", 1.0 / step)
        object.__setattr__(self, "covered", np.asarray(self.covered, dtype=bool))
        if self.covered.shape != (k,):
            raise ValueError("wake table coverage does not match its directions")

    @property
    def n_directions(self) -> int:
        return len(self.bin_start) - 1

    @property
    def n_entries(self) -> int:
        return int(self.bin_start[-1])

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, name).nbytes for name in _ARRAYS)

    # -- persistence -----------------------------------------------------------------------------------------------
    def save(self, path: Path | str) -> None:
        """Write to ``path`` (.npz) atomically (a temporary file renamed over it)."""
        path = Path(path)
        tmp = path.with_name(f".{path.name}.{np.random.default_rng().integers(1 << 62):x}.tmp")
        with open(tmp, "wb") as f:
            np.savez(f, format_version=FORMAT_VERSION, **{n: getattr(self, n) for n in _ARRAYS + _SCALARS})
        tmp.replace(path)

    @classmethod
    def load(cls, path: Path | str, key: str | None = None) -> WakeTables:
        """Read a saved table; ValueError if its format or its key (when given) is not the expected one."""
        with np.load(path, allow_pickle=False) as data:
            if int(data["format_version"]) != FORMAT_VERSION:
                raise ValueError(f"format {int(data['format_version'])}, expected {FORMAT_VERSION}")
            if key is not None and str(data["key"]) != key:
                raise ValueError(f"key {data['key']} is not {key}")
            arrays = {n: np.array(data[n]) for n in _ARRAYS}
            return cls(
                key=str(data["key"]),
                model=str(data["model"]),
                n_turbines=int(data["n_turbines"]),
                direction_step_deg=float(data["direction_step_deg"]),
                ambient_ti=float(data["ambient_ti"]),
                settings_json=str(data["settings_json"]),
                **arrays,
            )

    # -- combination -----------------------------------------------------------------------------------------------
    def _bin(self, k0: int) -> tuple[np.ndarray, ...]:
        """Entries of table directions k0 and k0 + 1 (cached): up, flat pair index, first-bin mask, table rows."""
        cached = self._cache.get(k0)
        if cached is None:
            k1 = (k0 + 1) % self.n_directions
            if not (self.covered[k0] and self.covered[k1]):
                raise ValueError(
                    f"wind direction {k0 * self.direction_step_deg:g}–{(k0 + 1) * self.direction_step_deg:g} "
                    "deg is outside the sector the wake tables cover"
                )
            idx = np.r_[self.bin_start[k0] : self.bin_start[k0 + 1], self.bin_start[k1] : self.bin_start[k1 + 1]]
            up = self.upstream[idx]
            first = np.arange(len(idx)) < self.bin_start[k0 + 1] - self.bin_start[k0]
            n_thrust, n_ti = len(self.thrust_grid), len(self.ti_grid)
            cached = (up, up * self.n_turbines + self.downstream[idx], first, idx * n_thrust, idx * (n_thrust * n_ti))
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[k0] = cached
        return cached

    def waked(
        self, direction_deg: float | np.ndarray, thrust: np.ndarray, free_speed: float | np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(waked speed m/s, turbulence intensity) of every turbine, for one farm or a batch of F farms.

        One farm: ``direction_deg`` a number, ``thrust`` (N,) each turbine's C_T or (N, N) with [i, j] the C_T of i
        as its wake reaches j (delayed), ``free_speed`` one value or (N,) each turbine's own (delayed) free stream;
        returns two (N,) arrays. A batch: ``direction_deg`` (F,), ``thrust`` (F, N) or (F, N, N), ``free_speed``
        (F,) or (F, N); returns two (F, N) arrays. Farms whose directions share a table interval are combined in one
        vectorised pass.
        """
        n = self.n_turbines
        single = np.ndim(direction_deg) == 0
        directions = np.atleast_1d(np.asarray(direction_deg, dtype=float))
        farms = len(directions)
        thrust = np.asarray(thrust, dtype=float)
        if single:
            thrust = thrust[None]
        if thrust.shape not in ((farms, n), (farms, n, n)):
            expected = f"({n},) or ({n}, {n})" if single else f"({farms}, {n}) or ({farms}, {n}, {n})"
            raise ValueError(f"thrust must have shape {expected}, got {thrust.shape[single:]}")
        free = np.asarray(free_speed, dtype=float)
        free = np.broadcast_to(free[..., None] if free.ndim == (0 if single else 1) else free, (farms, n))
        x = (directions % 360.0) / self.direction_step_deg
        k0 = np.floor(x).astype(np.intp) % self.n_directions
        w = x - np.floor(x)
        speed, ti = np.empty((farms, n)), np.empty((farms, n))
        for k in np.unique(k0):
            group = np.flatnonzero(k0 == k)
            speed[group], ti[group] = self._combine(self._bin(int(k)), w[group], thrust[group], free[group])
        return (speed[0], ti[0]) if single else (speed, ti)

    def _combine(self, entries, w, thrust, free) -> tuple[np.ndarray, np.ndarray]:
        """The module docstring's combination for G farms in one table interval (w: (G,), weight of k0 + 1)."""
        up, flat, first, row_m, row_mt = entries
        n = self.n_turbines
        g_farms = len(w)
        weight = np.where(first[None, :], 1.0 - w[:, None], w[:, None])  # (G, E)
        ct = thrust[:, up] if thrust.ndim == 2 else thrust.reshape(g_farms, -1)[:, flat]
        x = (1.0 - np.sqrt(1.0 - np.minimum(np.maximum(ct, 0.0), self._ct_max))) * self._inv_s_step
        m = np.minimum(x.astype(np.intp), self._m_last)
        f = x - m
        lin = row_m + m
        a = self.added_ti.reshape(-1)
        tau = a[lin] + (a[lin + 1] - a[lin]) * f
        scatter = (np.arange(g_farms)[:, None] * (n * n) + flat).reshape(-1)
        size = g_farms * n * n
        added = np.bincount(scatter, weights=(weight * tau).reshape(-1), minlength=size).reshape(g_farms, n, n)
        ti = np.sqrt(self.ambient_ti**2 + added.max(axis=1) ** 2)  # (G, N)
        d = self.deficit.reshape(-1)
        n_ti = len(self.ti_grid)
        if n_ti == 1:
            delta = d[lin] + (d[lin + 1] - d[lin]) * f
        else:
            y = np.minimum((ti[:, up] - self.ti_grid[0]) * self._inv_ti_step, n_ti - 1.0)
            t = np.minimum(y.astype(np.intp), n_ti - 2)
            h = y - t
            base = row_mt + m * n_ti + t
            low = d[base] + (d[base + 1] - d[base]) * h
            high = d[base + n_ti] + (d[base + n_ti + 1] - d[base + n_ti]) * h
            delta = low + (high - low) * f
        deficit = np.bincount(scatter, weights=(weight * delta).reshape(-1), minlength=size).reshape(g_farms, n, n)
        return free * (1.0 - np.sqrt(np.einsum("gij,gij->gj", deficit, deficit))), ti

    def _pair_index(self) -> tuple[np.ndarray, np.ndarray]:
        """The entries sorted by (table direction, downstream turbine) and where each (k, j) starts (cached)."""
        if not self._by_downstream:
            k = np.repeat(np.arange(self.n_directions), np.diff(self.bin_start))
            key = k * self.n_turbines + self.downstream
            order = np.argsort(key, kind="stable")
            start = np.searchsorted(key[order], np.arange(self.n_directions * self.n_turbines + 1))
            self._by_downstream.extend((order, start))
        return self._by_downstream[0], self._by_downstream[1]

    def waked_per_turbine(
        self, direction_deg: np.ndarray, thrust: np.ndarray, free_speed: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        r"""(waked speed m/s, turbulence intensity), each (F, N), of F farms whose turbines each see their own wind
        direction: ``direction_deg`` (F, N), θ_j the direction of the air at turbine j.

        The pairs (i, j) reaching j are looked up at θ_j (the direction the air carrying i's wake to j carries,
        ``plant_sim.farm.direction``), so column j is combined as ``waked`` combines it for a farm at θ_j:

        .. math::  \mathrm{TI}_j = \sqrt{\mathrm{TI}_0^2 + \max_i τ_{ij}(θ_j, C_{T,ij})^2},\qquad
                   v_j = U_j \Bigl(1 - \sqrt{\textstyle\sum_i δ_{ij}(θ_j, C_{T,ij}, \mathrm{TI}_i)^2}\Bigr)

        with TI_i i's own (at θ_i). ``thrust`` (F, N) or (F, N, N) and ``free_speed`` (F, N) as for ``waked``. With
        every θ_j equal it is ``waked`` at that direction. One ragged gather of each (farm, turbine)'s entries from
        the two table directions around its θ_j; no Python loop over farms, turbines or pairs.
        """
        n = self.n_turbines
        directions = np.asarray(direction_deg, dtype=float)
        if directions.ndim != 2 or directions.shape[1] != n:
            raise ValueError(f"direction_deg must have shape (farms, {n}), got {directions.shape}")
        farms = directions.shape[0]
        thrust = np.asarray(thrust, dtype=float)
        if thrust.shape not in ((farms, n), (farms, n, n)):
            raise ValueError(f"thrust must have shape ({farms}, {n}) or ({farms}, {n}, {n}), got {thrust.shape}")
        free = np.broadcast_to(np.asarray(free_speed, dtype=float), (farms, n))
        x = (directions % 360.0) / self.direction_step_deg
        k0 = np.floor(x).astype(np.intp) % self.n_directions
        k1 = (k0 + 1) % self.n_directions
        w = x - np.floor(x)
        outside = ~(self.covered[k0] & self.covered[k1])
        if outside.any():
            k = int(k0[outside][0])
            raise ValueError(
                f"wind direction {k * self.direction_step_deg:g}–{(k + 1) * self.direction_step_deg:g} "
                "deg is outside the sector the wake tables cover"
            )
        order, start = self._pair_index()
        column = np.arange(n)
        segments = np.stack([k0 * n + column, k1 * n + column])  # (2, F, N): the (direction, downstream) cells
        first, length = start[segments].reshape(-1), (start[segments + 1] - start[segments]).reshape(-1)
        total = int(length.sum())
        owner = np.repeat(np.arange(len(length)), length)  # which (bin, farm, turbine) segment each entry is of
        position = np.arange(total) - np.repeat(np.cumsum(length) - length, length) + first[owner]
        entry = order[position]
        farm = (owner // n) % farms
        down = owner % n
        up = self.upstream[entry]
        w_cell = w.reshape(-1)[owner % (farms * n)]
        weight = np.where(owner < farms * n, 1.0 - w_cell, w_cell)  # k0's entries 1 − w, k1's w
        ct = thrust[farm, up] if thrust.ndim == 2 else thrust[farm, up, down]
        s = (1.0 - np.sqrt(1.0 - np.minimum(np.maximum(ct, 0.0), self._ct_max))) * self._inv_s_step
        m = np.minimum(s.astype(np.intp), self._m_last)
        f = s - m
        n_thrust, n_ti = len(self.thrust_grid), len(self.ti_grid)
        lin = entry * n_thrust + m
        a = self.added_ti.reshape(-1)
        tau = a[lin] + (a[lin + 1] - a[lin]) * f
        scatter = (farm * n + up) * n + down
        size = farms * n * n
        added = np.bincount(scatter, weights=weight * tau, minlength=size).reshape(farms, n, n)
        ti = np.sqrt(self.ambient_ti**2 + added.max(axis=1) ** 2)  # (F, N)
        d = self.deficit.reshape(-1)
        if n_ti == 1:
            delta = d[lin] + (d[lin + 1] - d[lin]) * f
        else:
            y = np.minimum((ti[farm, up] - self.ti_grid[0]) * self._inv_ti_step, n_ti - 1.0)
            t = np.minimum(y.astype(np.intp), n_ti - 2)
            h = y - t
            base = entry * (n_thrust * n_ti) + m * n_ti + t
            low = d[base] + (d[base + 1] - d[base]) * h
            high = d[base + n_ti] + (d[base + n_ti + 1] - d[base + n_ti]) * h
            delta = low + (high - low) * f
        deficit = np.bincount(scatter, weights=weight * delta, minlength=size).reshape(farms, n, n)
        return free * (1.0 - np.sqrt(np.einsum("gij,gij->gj", deficit, deficit))), ti

    def waked_speeds(self, direction_deg: float, thrust: np.ndarray, free_speed: float | np.ndarray) -> np.ndarray:
        """Waked speed (N,) m/s of every turbine (``waked`` without the turbulence)."""
        return self.waked(direction_deg, thrust, free_speed)[0]

    def steady(
        self, direction_deg: float, free_speed: float | np.ndarray, thrust_of_speed, max_iterations: int | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(speed, C_T) of every turbine in steady state, each turbine's C_T = ``thrust_of_speed(its speed)``.

        Wakes only run downstream, so the fixed point is reached after as many sweeps as the longest chain of
        turbines in each other's wake (at most N + 1 sweeps).
        """
        n = self.n_turbines
        free = np.broadcast_to(np.asarray(free_speed, dtype=float), (n,))
        speed = free.copy()
        for _ in range(max_iterations or n + 1):
            ct = np.asarray(thrust_of_speed(speed), dtype=float)
            new = self.waked_speeds(direction_deg, ct, free)
            if np.array_equal(new, speed):
                break
            speed = new
        return speed, np.asarray(thrust_of_speed(speed), dtype=float)
