"""A wind direction that moves (plant_sim.farm.direction): the profile, the random veer, the travel geometry along
the actual direction, the wake tables' sector, the vane, bad input, and constant directions unchanged bit for bit.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from pydantic import ValidationError

from plant_sim.farm import FarmBatch
from plant_sim.farm.direction import (
    DirectionSeries,
    advected_distance,
    arrival_lookup,
    downwind_distances,
    gauss_markov,
)
from plant_sim.farm.floris_wakes import floris_model
from plant_sim.farm.plant import row_streams, vane_stream, veer_stream
from plant_sim.farm.wakes import plant_wake_tables
from tests.numeric_fingerprint import NumericFingerprint, expected, mismatches
from windwarden.evaluation.farm_scoring import farm_geometry
from wwcore.layout import FarmLayout
from wwcore.scenario.farm import VEER_BOUND_SIGMA, FarmDemand, FarmPlant
from wwcore.scenario.loader import ScenarioError, load_scenario, parse_scenario
from wwcore.scenario.wind import WindSpec, direction_at, unwrap_direction_points
from wwcore.turbine_params import BENCHMARK

DEMAND = FarmDemand(mode="available_fraction", fraction=0.8, update_s=10.0)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("wake-tables")


def moving(points, sigma: float = 0.0, time_s: float = 300.0, **kw) -> FarmPlant:
    kw.setdefault("demand", DEMAND)
    kw.setdefault("coherent_ti", 0.0)
    return FarmPlant(wake_model="gauss", wind_direction_profile=points, veer_sigma_deg=sigma, veer_time_s=time_s, **kw)


# ---- the profile ----------------------------------------------------------------------------------------------
def test_the_profile_is_linear_on_unwrapped_angles_along_the_shorter_arc():
    points = [(10.0, 350.0), (110.0, 10.0), (210.0, 30.0), (310.0, 300.0)]
    times, degrees = unwrap_direction_points(points)
    assert list(times) == [10.0, 110.0, 210.0, 310.0]
    assert list(degrees) == [350.0, 370.0, 390.0, 300.0]  # +20, +20, then −90 the short way (30 → 300)
    got = direction_at(points, [0.0, 10.0, 60.0, 110.0, 160.0, 260.0, 1000.0])
    np.testing.assert_allclose(got, [350.0, 350.0, 360.0, 370.0, 380.0, 345.0, 300.0])
    assert direction_at([(0.0, 5.0), (100.0, 355.0)], 100.0) == pytest.approx(-5.0)  # backing through north
    plant = moving(points)
    assert plant.direction_deg == 350.0 and plant.direction_varies
    assert plant.direction_sector_deg() == (300.0, 390.0)
    assert not moving([(0.0, 283.0)]).direction_varies  # one point: a constant direction


def test_the_wake_tables_cover_the_profile_and_the_veer_bound(cache):
    plant = moving([(0.0, 350.0), (100.0, 20.0)], sigma=2.0)
    lo, hi = plant.direction_sector_deg()
    assert (lo, hi) == (350.0 - VEER_BOUND_SIGMA * 2.0, 20.0 + 360.0 + VEER_BOUND_SIGMA * 2.0)
    tables = plant_wake_tables(plant, WindSpec(), BENCHMARK, cache)
    k = np.arange(tables.n_directions) * tables.direction_step_deg
    step = tables.direction_step_deg  # WakeSettings.covered keeps one table step either side
    inside = ((k - (lo - 5.0 - step)) % 360.0) <= (hi - lo + 10.0 + 2.0 * step)
    assert np.all(tables.covered[inside]) and not tables.covered[~inside].any()


# ---- the random veer --------------------------------------------------------------------------------------------
def test_the_gauss_markov_veer_has_its_stationary_sigma_and_correlation_time():
    """10⁶ samples at 0.1 s, T = 30 s (3300 correlation times): σ within 3 %, ρ(T) = e⁻¹ within 0.03, and the
    correlation time fitted from the lag-one correlation within 5 %."""
    dt, tau = 0.1, 30.0
    z = gauss_markov(np.random.default_rng(2024), 1_000_000, dt, tau)
    assert np.std(z) == pytest.approx(1.0, rel=0.03)
    lag = round(tau / dt)
    rho = np.dot(z[:-lag], z[lag:]) / np.dot(z, z)
    assert rho == pytest.approx(math.exp(-1.0), abs=0.03)
    phi = np.dot(z[:-1], z[1:]) / np.dot(z[:-1], z[:-1])
    assert -dt / math.log(phi) == pytest.approx(tau, rel=0.05)


def test_the_veer_is_bounded_and_has_its_own_stream():
    plant = moving([(0.0, 270.0)], sigma=3.0, time_s=20.0)
    rngs = [veer_stream(11, r) for r in range(4)]
    series = DirectionSeries(plant, rngs, 4, 3000.0)
    veer = series.deg - 270.0
    assert np.abs(veer).max() <= VEER_BOUND_SIGMA * 3.0 + 1e-12
    assert np.std(veer) == pytest.approx(3.0, rel=0.15)
    # its stream is none of the mast's, the vane's or a turbine's
    draws = {
        "veer": veer_stream(11, 0).standard_normal(4),
        "vane": vane_stream(11, 0).standard_normal(4),
        "mast": row_streams(11, 0, 0)[0].standard_normal(4),
        "mast noise": row_streams(11, 0, 0)[1].standard_normal(4),
    }
    values = [tuple(v) for v in draws.values()]
    assert len(set(values)) == len(values)


def test_switching_the_veer_on_changes_no_other_stream(cache):
    still, veering = moving([(0.0, 283.0)]), moving([(0.0, 283.0)], sigma=2.0)
    plants = [
        FarmBatch(p, WindSpec(mean=[(0.0, 9.0)]), [], seed=5, duration_s=5.0, runs=(0, 3), wake_cache_dir=cache)
        for p in (still, veering)
    ]
    np.testing.assert_array_equal(plants[0].mast.v, plants[1].mast.v)
    vanes = []
    for plant in plants:
        readings = []
        for _ in range(round(5.0 / plant.dt)):
            frame = plant.measure()
            plant.control(None)
            plant.advance()
            if frame.sample:
                readings.append(frame.mast_direction)
        vanes.append(np.array(readings))
    j = np.arange(1, len(vanes[0]) + 1)
    veer = plants[1].direction.deg[:, plants[1].direction.offset + j].T - 283.0  # (samples, runs)
    np.testing.assert_allclose((vanes[1] - vanes[0] + 180.0) % 360.0 - 180.0, veer, atol=1e-9)  # same noise
    assert np.abs(veer).max() > 0.0


# ---- constant directions are unchanged --------------------------------------------------------------------------
def fingerprint(plant_spec: FarmPlant, cache, seconds: float = 20.0) -> tuple[str, dict]:
    """(SHA-256 of the run's raw bits, for comparisons on one machine; its numeric fingerprint, across machines)."""
    wind = WindSpec(mean=[(0.0, 9.0), (20.0, 11.0)], turbulence_intensity=0.1)
    plant = FarmBatch(plant_spec, wind, [], seed=41, duration_s=seconds, runs=(0, 1), wake_cache_dir=cache)
    h = hashlib.sha256()
    sums = NumericFingerprint()
    for _ in range(round(seconds / plant.dt)):
        frame = plant.measure()
        plant.control(None)
        plant.advance()
        for name, arr in (("x", plant.turbines.x), ("mast_direction", frame.mast_direction), ("demand", frame.demand),
                          ("row_wind", plant.truth()["row_wind"])):  # fmt: skip
            h.update(np.asarray(arr).tobytes())
            sums.update(name, arr)
    return h.hexdigest(), sums.values()


def test_a_constant_direction_is_bit_identical_to_the_fixed_direction_code(cache):
    fixed_bits, fixed = fingerprint(FarmPlant(wake_model="gauss", wind_direction_deg=283.0, demand=DEMAND), cache)
    # the sums (tests/data/numeric_fingerprints.json) of the code before the direction could move: this function's
    # SHA-256 equalled that code's (main at 201829a) on the machine CI ran on through main at b2a8282, and the sums
    # were taken from b2a8282's code on a CPU with AVX-512, whose SIMD rounding moves the raw bits
    assert not mismatches(fixed, expected("farm_direction_gauss283"))
    rows = fingerprint(FarmPlant(wind_case=2, wake_model="rows", demand=DEMAND), cache)[1]
    assert not mismatches(rows, expected("farm_direction_rows2"))
    # a one-point profile is that constant direction, bit for bit on this machine
    assert fingerprint(moving([(0.0, 283.0)], coherent_ti=0.05), cache)[0] == fixed_bits


# ---- the direction carried with the wind --------------------------------------------------------------------------
def step(plant_spec: FarmPlant, seconds: float):
    """Run ``plant_spec`` (9 m/s, no turbulence) for ``seconds``; each farm sample's (t, vane, truth directions)."""
    wind = WindSpec(mean=[(0.0, 9.0)], turbulence_intensity=0.0)
    plant = FarmBatch(plant_spec, wind, [], seed=2, duration_s=seconds, wake_cache_dir=CACHE[0])
    out = []
    for _ in range(round(seconds / plant.dt)):
        frame = plant.measure()
        plant.control(None)
        if frame.sample:
            out.append((frame.t + plant.dt, float(frame.mast_direction[0]), plant.truth()["wind_direction"]))
        plant.advance()
    return plant, out


CACHE: list = []


def test_a_direction_step_reaches_each_turbine_at_its_own_delay(cache):
    """A step of the mast's direction 270° → 280° at t₀ = 5 s (over one farm sample), steady 9 m/s, no slow
    turbulence: turbine t sees 270° until the last old air reaches it, t₀ + d_t(270°)/v̄, and 280° once the first
    new air has, t₀ + 0.1 + d_t(280°)/v̄, d_t = d_mast + s_t its distance downwind of the mast along that direction
    (closed form, within one farm sample); the front row first; the vane reads the mast's 280° from t₀ + 0.1."""
    CACHE[:] = [cache]
    t0, seconds = 5.0, 260.0
    spec = moving([(0.0, 270.0), (t0, 270.0), (t0 + 0.1, 280.0)], mast_direction_noise_deg=0.0)
    plant, samples = step(spec, seconds)
    times = np.array([t for t, _, _ in samples])
    vane = np.array([v for _, v, _ in samples])
    seen = np.array([d for _, _, d in samples])  # (samples, N)
    np.testing.assert_allclose(vane, np.where(times >= t0 + 0.1 - 1e-9, 280.0, np.where(times <= t0, 270.0, vane)))
    layout = spec.resolved_layout()
    vbar = plant.mast.vbar[0, plant.mast.offset]
    assert np.ptp(plant.mast.vbar) < 1e-9
    old = t0 + (spec.mast_distance_m + downwind_distances(layout, 270.0)) / vbar  # last old air arrives
    new = t0 + 0.1 + (spec.mast_distance_m + downwind_distances(layout, 280.0)) / vbar  # first new air arrives
    assert new.max() < seconds - 10.0 and np.ptp(new) > 100.0  # every turbine reached, far apart
    for t in range(9):
        last_old = times[seen[:, t] <= 270.0 + 1e-9].max()
        first_new = times[seen[:, t] >= 280.0 - 1e-9].min()
        assert first_new == pytest.approx(new[t], abs=0.1 + 1e-9)
        assert last_old == pytest.approx(min(old[t], new[t]), abs=0.1 + 1e-9)
        assert np.all(np.diff(seen[:, t]) >= -1e-9)  # turns once, no going back
    front = np.argsort(downwind_distances(layout, 280.0))
    arrival = np.array([times[seen[:, t] >= 280.0 - 1e-9].min() for t in range(9)])
    assert np.all(np.diff(arrival[front]) >= 0.0) and arrival[front[0]] < arrival[front[-1]] - 150.0


def test_free_streams_and_directions_follow_the_air_each_turbine_sees(cache):
    """On a slowly moving direction and a steady wind, the free stream at sample j is the mast's at τ_t with
    τ_t + d_t(θ(τ_t))/v̄ = t (the air's own path), and the direction θ_t = θ(τ_t), not θ(t)."""
    plant_spec = moving([(0.0, 300.0), (1000.0, 310.0)])
    wind = WindSpec(mean=[(0.0, 8.0)])
    plant = FarmBatch(plant_spec, wind, [], seed=2, duration_s=400.0, wake_cache_dir=cache)
    assert np.ptp(plant.mast.vbar) < 1e-9  # a steady mean wind
    tau_all = plant.wakes._tau[0]  # (samples, N)
    layout = plant_spec.resolved_layout()
    for j in (30, 2500, 3900):
        t = j * 0.1
        tau = tau_all[j]
        theta = plant.direction.at_time(np.zeros(9, dtype=np.intp), tau)
        np.testing.assert_allclose(theta, 300.0 + 10.0 * np.maximum(tau, 0.0) / 1000.0, atol=1e-9)
        path = np.array([plant_spec.mast_distance_m + downwind_distances(layout, theta[k])[k] for k in range(9)])
        vbar = plant.mast.vbar[0, plant.mast.offset]
        np.testing.assert_allclose(tau + path / vbar, t, atol=1e-6)
    for _ in range(round(3.0 / plant.dt)):
        plant.measure()
        plant.control(None)
        plant.advance()
    j = plant.field.sample_index
    np.testing.assert_allclose(plant.wakes.lookup[0], tau_all[j], atol=0)
    np.testing.assert_allclose(plant.wakes.free_wind[0], plant.mast.at(np.zeros(9, dtype=int), tau_all[j]), atol=1e-12)
    np.testing.assert_allclose(plant.truth()["wind_direction"], 300.0, atol=1e-12)  # all air from before t = 0


def test_the_veer_is_carried_but_the_air_travels_along_the_profile(cache):
    """A random veer about a fixed 283° and a steady wind: every turbine's lookup is eq. (3)'s t − d_t(283°)/v̄
    (the veer does not bend the air's path, ``plant_sim.farm.direction``), and the direction it sees is the
    mast's of that time, veer included: the back row turns later than the front row."""
    spec = moving([(0.0, 283.0)], sigma=3.0, time_s=20.0)
    plant = FarmBatch(spec, WindSpec(mean=[(0.0, 9.0)]), [], seed=4, duration_s=100.0, wake_cache_dir=cache)
    assert np.ptp(plant.mast.vbar) < 1e-9
    d = spec.mast_distance_m + downwind_distances(spec.resolved_layout(), 283.0)
    t = np.arange(plant.wakes._tau.shape[1]) * 0.1
    np.testing.assert_allclose(plant.wakes._tau[0], t[:, None] - d[None, :] / plant.mast.vbar[0, 0], atol=1e-6)
    runs = np.zeros(plant.wakes._tau.shape, dtype=np.intp)[0]
    seen = plant.direction.at_time(runs, plant.wakes._tau[0])
    np.testing.assert_allclose(seen, np.interp(plant.wakes._tau[0], plant.direction.t, plant.direction.deg[0]))
    front, back = np.argmin(d), np.argmax(d)
    assert np.abs(seen[:, front] - seen[:, back]).max() > 1.0  # the veer reaches them at different times


def one_turbine() -> FarmLayout:
    return FarmLayout(x=np.array([0.0]), y=np.array([0.0]), rotor_diameter=115.0)


def test_the_advected_lookup_carries_the_field_at_the_mean_wind():
    """A gusting v̄, one direction: the lookup only moves forward, and the field it finds was carried d by the mean
    wind since (∫ v̄ dt from τ to t = d, within 1 cm), which eq. (3)'s t − d/v̄(t) is not (by over 1 m)."""
    rng = np.random.default_rng(3)
    times = np.arange(4000) * 0.1 - 200.0
    vbar = 9.0 + np.cumsum(rng.normal(0.0, 0.05, len(times)))
    advected = advected_distance(vbar)
    query = times[2500:3900]
    tau = arrival_lookup(times, advected, np.full(len(times), 270.0), one_turbine(), 1500.0, query)[:, 0]
    assert np.all(np.diff(tau) > 0.0)
    carried = advected[2500:3900] - np.interp(tau, times, advected)
    np.testing.assert_allclose(carried, 1500.0, atol=0.01)  # the arrival times are interpolated between samples
    naive = query - 1500.0 / vbar[2500:3900]
    assert np.abs(advected[2500:3900] - np.interp(naive, times, advected) - 1500.0).max() > 1.0


def test_newer_air_overtakes_and_the_turbine_holds_across_a_gap():
    """Two turbines 1000 m apart north–south, v̄ = 10 m/s, the mast 100 m upwind of the farm's edge. From the north
    (0°) turbine 2 (south) is 1100 m from the mast; from the west (270°) both are 100 m. The direction swings 0° →
    270° at 10 s: the new air reaches turbine 2 at 10 + 100/10 = 20 s, while old air still arrives until
    10 + 1100/10 = 120 s: the newer wins (overtaking), τ jumps to 10 s. Then back to 0° at 50 s: the last west air
    reaches it at 50 + 10 = 60 s, the first north air at 50 + 110 = 160 s; in between it holds (τ moves through
    one sample only)."""
    layout = FarmLayout(x=np.array([0.0, 0.0]), y=np.array([0.0, -1000.0]), rotor_diameter=115.0)
    times = np.arange(-2000, 3000) * 0.1
    direction = np.where((times > 10.0) & (times <= 50.0), 270.0, 360.0)
    advected = advected_distance(np.full(len(times), 10.0))
    query = np.arange(0, 2500) * 0.1
    tau = arrival_lookup(times, advected, direction, layout, 100.0, query)[:, 1]
    at = dict(zip(np.round(query, 1), tau, strict=True))
    assert at[19.0] == pytest.approx(19.0 - 110.0)  # old north air
    assert at[20.5] == pytest.approx(10.5, abs=1e-9)  # new west air, 10 s after it passed the mast
    assert at[59.5] == pytest.approx(49.5, abs=1e-9)
    assert 50.0 <= at[100.0] <= 50.1 and 50.0 <= at[159.0] <= 50.1  # held between the last west and first north air
    assert at[170.0] == pytest.approx(170.0 - 110.0, abs=1e-9)
    assert np.all(np.diff(tau) >= 0.0)


@pytest.mark.parametrize("direction", [271.5, 313.25])
def test_steady_winds_between_table_directions_equal_floris(cache, direction):
    """t = 0 is the steady state at the run's own direction, between the tables' 1° steps: FLORIS's within 0.1 m/s
    (the existing fixed-direction test asks 0.05 on table directions; the rest is the tables' linear
    interpolation in θ)."""
    plant_spec = moving([(0.0, direction), (600.0, direction + 5.0)])
    for speed in (8.0, 11.0):
        plant = FarmBatch(
            plant_spec, WindSpec(mean=[(0.0, speed)], turbulence_intensity=0.10), [], seed=1, duration_s=1.0,
            wake_cache_dir=cache,
        )  # fmt: skip
        fm = floris_model(plant_spec.resolved_layout(), "gauss", BENCHMARK, [direction], [speed], 0.10)
        fm.run()
        ref = fm.turbine_average_velocities[0]
        assert ref.min() < speed - 0.5  # waked
        assert np.abs(plant.field.turbine_wind[0] - ref).max() < 0.1


# ---- bad input ----------------------------------------------------------------------------------------------------
BASE = {
    "name": "veer-check",
    "duration_s": 10.0,
    "plant": {"kind": "farm", "wake_model": "gauss", "wind_direction_profile": [[0.0, 270.0], [5.0, 280.0]]},
}


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        ({"wind_direction_profile": []}, "plant.wind_direction_profile", "at least one"),
        ({"wind_direction_profile": [[0.0, 360.0]]}, "plant.wind_direction_profile", "outside 0"),
        ({"wind_direction_profile": [[5.0, 270.0], [5.0, 280.0]]}, "plant.wind_direction_profile", "increase"),
        ({"wind_direction_profile": [[-1.0, 270.0]]}, "plant.wind_direction_profile", "≥ 0"),
        ({"wind_direction_profile": [[0.0, 10.0], [9.0, 190.0]]}, "plant.wind_direction_profile", "ambiguous"),
        ({"wind_direction_deg": 270.0}, "wind_direction_profile", "not both"),
        ({"wake_model": "rows"}, "wind_direction_profile", "row model"),
        ({"veer_sigma_deg": 25.0}, "plant.veer_sigma_deg", "less than or equal"),
        ({"veer_sigma_deg": -1.0}, "plant.veer_sigma_deg", "greater than or equal"),
        ({"veer_time_s": 1.0}, "plant.veer_time_s", "greater than or equal"),
        ({"wind_direction_profile": None, "veer_sigma_deg": 2.0}, "veer_sigma_deg", "wind_direction_deg"),
    ],
)
def test_bad_direction_settings_are_refused_with_a_clear_message(change, field, words):
    raw = {**BASE, "plant": {**BASE["plant"], **change}}
    raw["plant"] = {k: v for k, v in raw["plant"].items() if v is not None}
    before = repr(raw)
    with pytest.raises(ScenarioError) as err:
        parse_scenario(raw)
    assert field in str(err.value) and words in str(err.value)
    assert repr(raw) == before  # nothing changed
    with pytest.raises(ValidationError):
        FarmPlant(**raw["plant"])


def test_the_shipped_veer_scenario_reads_and_moves():
    scenario = load_scenario("farm-3x3-veer")
    plant = scenario.plant
    assert plant.direction_varies and plant.direction_deg == 270.0
    assert plant.direction_profile_deg(1200.0) == pytest.approx(300.0)
    assert not plant.is_paper_farm()


def test_the_demand_reads_the_free_streams_the_turbines_see(cache):
    """The delta-control demand's free streams (``free_stream_series``) are the plant's, sample for sample, under a
    veering, gusting wind."""
    plant_spec = moving([(0.0, 280.0), (30.0, 292.0)], sigma=3.0, time_s=20.0, coherent_ti=0.08)
    plant = FarmBatch(plant_spec, WindSpec(mean=[(0.0, 9.0)]), [], seed=8, duration_s=4.0, runs=(0, 2),
                      wake_cache_dir=cache)  # fmt: skip
    series = plant.wakes.free_stream_series(41)  # (runs, samples, N)
    for k in range(round(4.0 / plant.dt)):
        plant.measure()
        plant.control(None)
        plant.advance()
        if (k + 1) % plant.ticks_per_sample == 0:
            j = plant.field.sample_index
            np.testing.assert_allclose(plant.wakes.free_wind, series[:, j], rtol=0, atol=1e-12)


def test_a_moving_direction_reads_back_and_the_scorecard_names_it():
    plant = load_scenario("farm-3x3-veer").plant
    again = FarmPlant.model_validate(plant.model_dump())  # the live adapter's round trip
    assert again == plant and again.direction_sector_deg() == plant.direction_sector_deg()
    geometry = farm_geometry(load_scenario("farm-3x3-veer"))
    assert geometry["wind_direction_deg"] == 270.0 and geometry["veer_sigma_deg"] == 2.0
    assert geometry["wind_direction_range_deg"] == [270.0 - 8.0, 300.0 + 8.0]
    assert "wind_direction_range_deg" not in farm_geometry(load_scenario("farm-hornsrev1"))


@pytest.mark.slow
def test_running_plant_equals_floris_once_a_veer_has_crossed_the_farm(cache):
    """The running 3 × 3 at 9 m/s, TI 0.03 (as ``test_farm_wakes``'s running test), the mast's direction turning
    from 266.5° to 271.5° over the first 10 s (between two table directions): at 100 s the front row sees 271.5°
    and the back row still 266.5°; once the new air has crossed the farm (≈ 211 s) and the wakes have settled, each
    turbine's mean wind over the last 20 s equals FLORIS's at 271.5° within 0.1 m/s."""
    spec = moving([(0.0, 266.5), (10.0, 271.5)], wake_added_turbulence=False)
    wind = WindSpec(mean=[(0.0, 9.0)], turbulence_intensity=0.03)
    seconds = 300.0
    plant = FarmBatch(spec, wind, [], seed=7, duration_s=seconds, wake_cache_dir=cache)
    winds, at_100 = [], None
    for k in range(round(seconds / plant.dt)):
        frame = plant.measure()
        plant.control(None)
        if frame.sample and (k + 1) * plant.dt > seconds - 20.0:
            winds.append(plant.truth()["row_wind"])
        if frame.sample and k + 1 == round(100.0 / plant.dt):
            at_100 = plant.truth()["wind_direction"]
        plant.advance()
    s = downwind_distances(spec.resolved_layout(), 271.5)
    np.testing.assert_allclose(at_100[s < 1.0], 271.5)
    np.testing.assert_allclose(at_100[s > s.max() - 1.0], 266.5)
    np.testing.assert_allclose(plant.truth()["wind_direction"], 271.5)
    fm = floris_model(spec.resolved_layout(), "gauss", BENCHMARK, [271.5], [9.0], 0.03)
    fm.run()
    ref = fm.turbine_average_velocities[0]
    assert ref.min() < 8.0  # waked
    assert np.abs(np.mean(winds, axis=0) - ref).max() < 0.1
