r"""Wake tables computed by FLORIS (NREL's engineering wake library), cached on disk; direct FLORIS runs of a farm.

**What FLORIS computes.** For every ordered turbine pair (i upstream of j) and every wind direction θ_k of a grid
(step ``direction_step_deg``), FLORIS's own wake-model functions give

* δ_ij(θ_k, C_T, TI_i): the fraction of the free stream that i's wake alone takes from j's rotor, i.e.
  1 − (mean over j's 3 × 3 rotor points of (1 − d_p)³)^{1/3} with d_p FLORIS's velocity deficit at point p (its
  cubic-mean rotor average), on a grid of i's thrust coefficient C_T and i's turbulence intensity TI_i;
* τ_ij(θ_k, C_T): the turbulence intensity i's wake adds at j (FLORIS's wake-added turbulence model times the share
  of j's rotor points that i's wake slows by more than 0.05 m/s at ``reference_speed_mps``, within 15 D downstream
  and 2 D across, as FLORIS's sequential solver applies it).

The physics is FLORIS's: the velocity-deficit, deflection and turbulence models are called from the configured
``FlorisModel`` (``core.wake.velocity_model.function`` etc.) on FLORIS's own rotor grid (``core.grid``, 3 × 3
points, rotated by FLORIS for each direction). What this module adds is the loop FLORIS's ``sequential_solver``
runs, unrolled over pairs instead of turbines. ``plant_sim.farm.wake_tables`` combines the tables.

**Models.** ``gauss`` (default): FLORIS's Gauss velocity deficit (Bastankhah & Porté-Agel 2016, with the near
wake of Niayifar & Porté-Agel) and Gauss deflection, Crespo–Hernández wake-added turbulence, sum-of-squares
free-stream superposition, FLORIS's default parameters (α 0.58, β 0.077, k_a 0.38, k_b 0.004), with the
Gauss–curl-hybrid extras (secondary steering, yaw-added recovery, transverse velocities) off. At zero yaw GCH
differs from plain Gauss only by the mixing its wake-rotation vortex adds, which pairwise tables cannot carry; the
difference is measured in docs/farm-wakes.md. ``jensen``: FLORIS's Jensen/Park deficit (w_e = 0.05) with Jiménez
deflection, same superposition; it does not depend on turbulence.

**Indexing.** A deficit *fraction* from FLORIS's Gauss or Jensen model depends on C_T, TI and geometry, not on the
wind speed, so the tables are indexed by (θ, C_T, TI) only. The speed enters FLORIS's wake-added turbulence
through its 0.05 m/s overlap threshold, taken at ``reference_speed_mps``. The inflow is uniform (no shear in
FLORIS): the plant puts its own shear on each turbine's mean wind.

**Cache.** Tables are stored as ``<cache_dir>/wakes-<key>.npz``, key the SHA-256 of the layout's positions and D,
the settings, the FLORIS version and the table format: a second start with the same farm loads them
(``plant_sim.farm.wake_cache``, which does not import FLORIS).
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from floris import FlorisModel

from plant_sim.farm.operating_curve import rated_curve
from plant_sim.farm.wake_cache import WakeSettings, cached_wake_tables
from plant_sim.farm.wake_tables import WakeTables
from wwcore.layout import FarmLayout
from wwcore.turbine_params import TurbineParams

log = logging.getLogger(__name__)

MODEL_STRINGS = {
    "gauss": {
        "velocity_model": "gauss",
        "deflection_model": "gauss",
        "turbulence_model": "crespo_hernandez",
        "combination_model": "sosfs",
    },
    "jensen": {
        "velocity_model": "jensen",
        "deflection_model": "jimenez",
        "turbulence_model": "crespo_hernandez",
        "combination_model": "sosfs",
    },
}
OVERLAP_THRESHOLD_MPS = 0.05  # m/s, FLORIS's sequential solver: a rotor point is "in the wake" past this deficit
ADDED_TI_REACH_D = 15.0  # D, FLORIS's sequential solver: wake-added turbulence acts this far downstream
ADDED_TI_WIDTH_D = 2.0  # D, … and this far across
CANDIDATE_REACH = (2.5, 0.35)  # (D, –): pairs with |Δy| > 2.5 D + 0.35 Δx are never evaluated (4σ at TI 0.2)
CHUNK_POINTS = 2_000_000  # rotor points per call of FLORIS's model functions


def benchmark_turbine(params: TurbineParams) -> dict:
    """FLORIS turbine definition of the farm turbine: its steady power and C_T curves (``operating_curve``)."""
    winds, power, ct = rated_curve(params)
    return {
        "turbine_type": "windwarden_benchmark_4p8mw",
        "hub_height": params.hub_height,
        "rotor_diameter": 2.0 * params.radius,
        "TSR": params.lambda_opt,
        "operation_model": "simple",
        "power_thrust_table": {
            "ref_air_density": params.rho,
            "ref_tilt": 0.0,
            "cosine_loss_exponent_yaw": 1.88,
            "cosine_loss_exponent_tilt": 1.88,
            "wind_speed": winds.tolist(),
            "power": (power / 1e3).tolist(),  # kW
            "thrust_coefficient": ct.tolist(),
        },
    }


def floris_model(
    layout: FarmLayout,
    model: str,
    params: TurbineParams,
    directions_deg: np.ndarray,
    speeds_mps: np.ndarray,
    turbulence_intensity: float | np.ndarray,
    *,
    turbine: dict | None = None,
    gch: bool = False,
) -> FlorisModel:
    """A FlorisModel of the farm, one condition per (direction, speed) pair; ``gch`` keeps FLORIS's GCH extras."""
    config = FlorisModel.get_defaults()
    config["logging"]["console"]["enable"] = False
    config["wake"]["model_strings"] = dict(MODEL_STRINGS[model])
    for flag in ("enable_secondary_steering", "enable_yaw_added_recovery", "enable_transverse_velocities"):
        config["wake"][flag] = gch
    config["farm"]["turbine_type"] = [turbine or benchmark_turbine(params)]
    config["flow_field"]["wind_shear"] = 0.0
    config["flow_field"]["reference_wind_height"] = params.hub_height
    config["flow_field"]["air_density"] = params.rho
    fm = FlorisModel(config)
    directions = np.asarray(directions_deg, dtype=float)
    fm.set(
        layout_x=layout.x,
        layout_y=layout.y,
        wind_directions=directions,
        wind_speeds=np.asarray(speeds_mps, dtype=float),
        turbulence_intensities=np.broadcast_to(np.asarray(turbulence_intensity, dtype=float), directions.shape),
    )
    return fm


def wake_tables(
    layout: FarmLayout,
    settings: WakeSettings | None = None,
    params: TurbineParams | None = None,
    cache_dir: Path | str | None = None,
) -> WakeTables:
    """The farm's wake tables: loaded from the cache when built before with the same key, else built and stored."""
    settings = settings or WakeSettings()
    params = params or TurbineParams()
    key, file, tables = cached_wake_tables(layout, settings, params, cache_dir)
    if tables is not None:
        return tables
    start = time.perf_counter()
    tables = build_wake_tables(layout, settings, params, key)
    log.info("wake tables for %d turbines built in %.1f s", layout.n_turbines, time.perf_counter() - start)
    file.parent.mkdir(parents=True, exist_ok=True)
    tables.save(file)
    return tables


def build_wake_tables(layout: FarmLayout, settings: WakeSettings, params: TurbineParams, key: str = "") -> WakeTables:
    """Evaluate FLORIS's wake models on every candidate (direction, pair) and every (C_T, TI) grid node."""
    n_dir = round(360.0 / settings.direction_step_deg)
    if not math.isclose(n_dir * settings.direction_step_deg, 360.0, abs_tol=1e-9):
        raise ValueError(f"direction_step_deg {settings.direction_step_deg} does not divide 360")
    directions = np.arange(n_dir) * settings.direction_step_deg
    ti0 = settings.turbulence_intensity
    fm = floris_model(layout, settings.model, params, directions, np.full(n_dir, settings.reference_speed_mps), ti0)
    fm.core.initialize_domain()
    grid = fm.core.grid
    unsort = grid.unsorted_indices
    pts = {c: np.take_along_axis(getattr(grid, f"{c}_sorted"), unsort, axis=1) for c in "xyz"}  # (K, N, 3, 3)
    u0 = np.take_along_axis(fm.core.flow_field.u_initial_sorted, unsort, axis=1)
    centre = {c: pts[c].mean(axis=(2, 3)) for c in "xyz"}  # (K, N)
    d = 2.0 * params.radius
    dx = centre["x"][:, None, :] - centre["x"][:, :, None]  # (K, i, j): j downstream of i by dx
    dy = np.abs(centre["y"][:, None, :] - centre["y"][:, :, None])
    covered = settings.covered(directions)[:, None, None]
    s_grid = np.linspace(0.0, 1.0 - math.sqrt(1.0 - settings.thrust_max), settings.thrust_points)
    ct_grid = 1.0 - (1.0 - s_grid) ** 2
    wake = fm.core.wake
    shape = dx.shape

    # wake-added turbulence (i at ambient TI, at the reference speed): FLORIS adds it within 15 D and 2 D
    near = (dx > 0.1) & (dx <= ADDED_TI_REACH_D * d + 0.1) & (dy < (ADDED_TI_WIDTH_D + 0.5) * d) & covered
    ti_entries = np.nonzero(near)
    added = _evaluate(wake, pts, u0, centre, ti_entries, ct_grid[1:], np.array([ti0]), d, params, ti0, True)[..., 0]
    if settings.model == "gauss":
        top = math.sqrt(ti0**2 + float(added.max(initial=0.0)) ** 2)
        ti_grid = np.linspace(ti0, max(top, ti0 * 1.001), settings.ti_points)
    else:
        ti_grid = np.array([ti0])  # Jensen's deficit does not depend on turbulence
    # velocity deficits wherever the wake can reach a rotor point (a pre-filter; small values are dropped below)
    reach = _reach(wake.velocity_model, settings.model, float(ti_grid[-1]), d, dx)
    wake_entries = np.nonzero((dx > 0.1) & (dy <= reach) & covered)
    deficit = _evaluate(wake, pts, u0, centre, wake_entries, ct_grid[1:], ti_grid, d, params, ti0, False)

    flat_ti = np.ravel_multi_index(ti_entries, shape)
    flat_wake = np.ravel_multi_index(wake_entries, shape)
    flat = np.union1d(flat_ti, flat_wake)  # sorted: by direction first
    table_added = np.zeros((len(flat), len(s_grid)), dtype=np.float32)
    table_added[np.searchsorted(flat, flat_ti), 1:] = added
    table_deficit = np.zeros((len(flat), len(s_grid), len(ti_grid)), dtype=np.float32)
    table_deficit[np.searchsorted(flat, flat_wake), 1:, :] = deficit
    keep = (table_deficit.max(axis=(1, 2)) >= settings.min_deficit) | (table_added.max(axis=1) >= settings.min_deficit)
    k, i, j = np.unravel_index(flat[keep], shape)
    return WakeTables(
        key=key,
        model=settings.model,
        n_turbines=layout.n_turbines,
        direction_step_deg=settings.direction_step_deg,
        bin_start=np.concatenate([[0], np.cumsum(np.bincount(k, minlength=n_dir))]).astype(np.int64),
        upstream=i.astype(np.int32),
        downstream=j.astype(np.int32),
        thrust_grid=ct_grid,
        ti_grid=ti_grid,
        deficit=table_deficit[keep],
        added_ti=table_added[keep],
        ambient_ti=ti0,
        covered=covered[:, 0, 0],
        settings_json=settings.model_dump_json(),
    )


def _reach(model, name: str, ti_top: float, d: float, dx: np.ndarray) -> np.ndarray:
    """|Δy| (m) beyond which i's wake cannot reach any of j's rotor points by more than 1e-5 of the free stream.

    Gauss: the wake's σ ≤ k_y Δx + 0.36 D (FLORIS's σ_y0 ≤ D/(2√2), near-wake σ ≤ 0.36 D) with k_y = k_a TI + k_b at
    the largest TI; a rotor point D/4 off the centre line sees C e^{−r²/2σ²} ≤ 1e-5 past 4.8 σ. Jensen: the top hat
    R + w_e Δx, plus D/4. Other models: 2.5 D + 0.35 Δx.
    """
    if name == "gauss":
        return 0.25 * d + 4.8 * ((model.ka * ti_top + model.kb) * dx + 0.36 * d)
    if name == "jensen":
        return 0.75 * d + model.we * dx
    return CANDIDATE_REACH[0] * d + CANDIDATE_REACH[1] * dx


def _deflection(model, x_i, y_i, ti, ct, diameter, grid, flow, n_levels: int) -> np.ndarray:
    """FLORIS's wake deflection at zero yaw, (entries × levels, 1, 3, 3).

    At zero yaw both FLORIS deflection models reduce to a_d + b_d Δx, the same at every C_T and TI level; it is
    evaluated at the first and last level of each entry and, when they agree, spread over the levels (the Gauss
    deflection costs as much as the deficit itself). Otherwise every level is evaluated.
    """
    ends = np.r_[0, n_levels - 1]
    rows = (np.arange(len(ct)) // n_levels * n_levels)[::n_levels][:, None] + ends[None, :]
    rows = rows.reshape(-1)

    def call(r):
        sub_grid = SimpleNamespace(**{n: getattr(grid, n)[r] for n in ("x_sorted", "y_sorted", "z_sorted")})
        sub_flow = SimpleNamespace(u_initial_sorted=flow.u_initial_sorted[r], wind_veer=flow.wind_veer)
        kwargs = model.prepare_function(sub_grid, sub_flow)
        return model.function(x_i[r], y_i[r], np.zeros_like(ct[r]), ti[r], ct[r], diameter[r], **kwargs)

    pair = np.broadcast_to(call(rows), (len(rows), *grid.x_sorted.shape[1:])).reshape(-1, 2, *grid.x_sorted.shape[1:])
    if np.allclose(pair[:, 0], pair[:, 1], rtol=0.0, atol=1e-6):
        return np.repeat(pair[:, 0], n_levels, axis=0)
    return call(np.arange(len(ct)))


def _evaluate(wake, pts, u0, centre, entries, cts, tis, d, params, ti0, added_ti: bool) -> np.ndarray:
    """FLORIS's models on each entry (k, i, j) × C_T × TI: δ (rotor-averaged deficit fraction) or τ (added TI).

    Entries are evaluated in order of their downwind distance, so that a chunk rarely mixes FLORIS's near and far
    wake (the Gauss model computes its near-wake branch for a whole array if any point is in it); float32.
    """
    order = np.argsort(centre["x"][entries[0], entries[2]] - centre["x"][entries[0], entries[1]], kind="stable")
    k, i, j = (e[order] for e in entries)
    n_levels = len(cts) * len(tis)
    out = np.zeros((len(k), len(cts), len(tis)), dtype=np.float32)
    rows = max(1, CHUNK_POINTS // (9 * n_levels))
    ct_l = np.repeat(cts, len(tis)).astype(np.float32)[None, :]
    ti_l = np.tile(tis, len(cts)).astype(np.float32)[None, :]
    for lo in range(0, len(k), rows):
        sl = slice(lo, lo + rows)
        kk, ii, jj = k[sl], i[sl], j[sl]
        m = len(kk) * n_levels

        def rotor(a, kk=kk, jj=jj):  # (entries, 3, 3) of j → (entries × levels, 1, 3, 3)
            return np.repeat(a[kk, jj].astype(np.float32), n_levels, axis=0)[:, None]

        def source(a, kk=kk, ii=ii):  # (entries,) of i → (entries × levels, 1, 1, 1)
            return np.repeat(a[kk, ii].astype(np.float32), n_levels)[:, None, None, None]

        x, y, z, u = rotor(pts["x"]), rotor(pts["y"]), rotor(pts["z"]), rotor(u0)
        x_i, y_i, z_i = source(centre["x"]), source(centre["y"]), source(centre["z"])
        ct = np.broadcast_to(ct_l, (len(kk), n_levels)).reshape(m)[:, None, None, None]
        ti = np.broadcast_to(ti_l, (len(kk), n_levels)).reshape(m)[:, None, None, None]
        a_i = (1.0 - np.sqrt(1.0 - ct)) / 2.0  # FLORIS's "simple" operation model's axial induction
        zeros = np.zeros_like(ct)
        diameter, hub = np.full_like(ct, d), np.full_like(ct, params.hub_height)
        ti0 = np.float32(ti0)
        proxy_grid = SimpleNamespace(x_sorted=x, y_sorted=y, z_sorted=z)
        proxy_flow = SimpleNamespace(u_initial_sorted=u, wind_veer=0.0)
        deflection = _deflection(wake.deflection_model, x_i, y_i, ti, ct, diameter, proxy_grid, proxy_flow, n_levels)
        velocity = wake.velocity_model.function(
            x_i, y_i, z_i, a_i, deflection, zeros, ti, ct, hub, diameter,
            **wake.velocity_model.prepare_function(proxy_grid, proxy_flow),
        )  # fmt: skip
        if added_ti:
            overlap = np.mean(velocity * u > OVERLAP_THRESHOLD_MPS, axis=(2, 3), keepdims=True)
            ti_wake = np.nan_to_num(wake.turbulence_model.function(ti0, x, x_i, diameter, a_i), posinf=0.0)
            mask = (x > x_i) & (np.abs(y_i - y) < ADDED_TI_WIDTH_D * d) & (x <= ADDED_TI_REACH_D * d + x_i)
            value = np.mean(overlap * ti_wake * mask, axis=(1, 2, 3))
        else:
            value = 1.0 - np.cbrt(np.mean((1.0 - velocity) ** 3, axis=(1, 2, 3)))
        out[order[sl]] = value.reshape(len(kk), len(cts), len(tis))
    return out
