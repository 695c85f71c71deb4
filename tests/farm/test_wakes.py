"""Wake tables from FLORIS (plant_sim.farm.floris_wakes, wake_tables) against direct FLORIS runs of the same farm.

Direct runs use the benchmark turbine's FLORIS definition (steady power and C_T curves); the tables are fed the
C_T FLORIS computed for each turbine, so both see the same thrust. Horns Rev 1 is tabulated over a 20 deg sector
around 270 deg to keep the suite short (the full circle is the same code, ``tools/bench_wakes.py`` times it).
"""

from __future__ import annotations

import hashlib
import json
import logging
import subprocess
import sys

import floris
import numpy as np
import pytest

from plant_sim.farm import floris_wakes, wake_cache
from plant_sim.farm.floris_wakes import WakeSettings, floris_model, wake_tables
from plant_sim.farm.wake_tables import FORMAT_VERSION, WakeTables
from plant_sim.farm.wakes import plant_wake_tables
from wwcore.backend import fast_module
from wwcore.layout import HORNS_REV_1, SEED001_DIRECTIONS_DEG, SEED001_LAYOUT, FarmLayout
from wwcore.scenario import load_scenario
from wwcore.turbine_params import BENCHMARK

D = 2.0 * BENCHMARK.radius
SPEEDS = np.array([6.0, 9.0, 11.5, 14.0, 18.0])  # m/s, below and above rated (≈ 12.9 m/s)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("wakes")


@pytest.fixture(scope="module")
def seed001():
    return SEED001_LAYOUT.resolve(D)


@pytest.fixture(scope="module")
def tables_3x3(seed001, cache):
    return {m: wake_tables(seed001, WakeSettings(model=m), BENCHMARK, cache) for m in ("gauss", "jensen")}


def direct(layout, model, direction, speeds=SPEEDS, ti=0.10):
    fm = floris_model(layout, model, BENCHMARK, np.full(len(speeds), direction), speeds, ti)
    fm.run()
    return fm.turbine_average_velocities, fm.get_turbine_thrust_coefficients(), fm.get_turbine_TIs()


def table_speeds(tables, direction, cts, speeds=SPEEDS):
    return np.array([tables.waked_speeds(direction, ct, u) for ct, u in zip(cts, speeds, strict=True)])


@pytest.mark.parametrize("model", ["gauss", "jensen"])
@pytest.mark.parametrize("case", [1, 2])
def test_3x3_tables_equal_floris(tables_3x3, seed001, model, case):
    direction = SEED001_DIRECTIONS_DEG[case]
    v, ct, ti = direct(seed001, model, direction)
    got = table_speeds(tables_3x3[model], direction, ct)
    assert np.abs(got - v).max() < 0.05  # m/s; the issue asks for 0.1
    assert np.all(v.min(axis=1) < SPEEDS - 0.5)  # the comparison is not between two unwaked farms
    turbulence = np.array([tables_3x3[model].waked(direction, c, u)[1] for c, u in zip(ct, SPEEDS, strict=True)])
    if model == "gauss":
        assert np.abs(turbulence - ti).max() < 0.002


def test_case2_wakes_only_the_turbines_floris_wakes(tables_3x3, seed001):
    """Diagonal wind (315°): turbines 2, 3, 4 and 7 stand in the free stream, 5, 6, 8 and 9 in wakes (1→5→9, 2→6,
    4→8), in FLORIS and in the tables alike; the row model of seed 001 wakes all but turbine 1."""
    free = np.array([2, 3, 4, 7]) - 1
    waked = np.array([5, 6, 8, 9]) - 1
    for model in ("gauss", "jensen"):
        v, ct, _ = direct(seed001, model, 315.0, np.array([11.0]))
        got = tables_3x3[model].waked_speeds(315.0, ct[0], 11.0)
        for speeds in (v[0], got):
            assert np.all(speeds[free] > 11.0 - 0.02), (model, speeds)
            assert np.all(speeds[waked] < 11.0 - 0.8), (model, speeds)
            assert speeds[0] == pytest.approx(11.0, abs=1e-9)


def test_off_grid_directions_interpolate(tables_3x3, seed001):
    """Between table directions the Gauss tables stay within 0.03 m/s of FLORIS (smooth in direction); Jensen's top
    hat on FLORIS's 3 × 3 rotor points is discontinuous in direction, so only its on-grid values are exact."""
    for direction in (271.5, 300.3, 314.6):
        v, ct, _ = direct(seed001, "gauss", direction)
        assert np.abs(table_speeds(tables_3x3["gauss"], direction, ct) - v).max() < 0.03


@pytest.fixture(scope="module")
def horns_rev(cache):
    layout = HORNS_REV_1.resolve(D)
    settings = {m: WakeSettings(model=m, sector_deg=(260.0, 280.0)) for m in ("gauss", "jensen")}
    return layout, {m: wake_tables(layout, s, BENCHMARK, cache) for m, s in settings.items()}


@pytest.mark.parametrize("model", ["gauss", "jensen"])
def test_horns_rev_tables_equal_floris(horns_rev, model):
    layout, tables = horns_rev
    speeds = np.array([8.0, 11.0, 14.0])
    for direction in (270.0, 273.0):
        v, ct, _ = direct(layout, model, direction, speeds)
        got = table_speeds(tables[model], direction, ct, speeds)
        assert np.abs(got - v).max() < 0.05
        assert np.all(v.min(axis=1) < speeds - 1.0)  # deep-array turbines are waked
    with pytest.raises(ValueError, match="outside the sector"):
        tables[model].waked_speeds(180.0, np.full(80, 0.7), 10.0)


def test_steady_state_equals_floris_sequential_solve(tables_3x3, seed001):
    """With each turbine's C_T taken from its own waked wind (the turbine curve), the tables' fixed point is FLORIS's
    own solution: FLORIS computes C_T the same way, front to back."""
    curve = floris_wakes.benchmark_turbine(BENCHMARK)["power_thrust_table"]

    def thrust_of_speed(v):
        return np.interp(v, curve["wind_speed"], curve["thrust_coefficient"])

    for model in ("gauss", "jensen"):
        for direction in (270.0, 315.0):
            v, _, _ = direct(seed001, model, direction)
            for f, u in enumerate(SPEEDS):
                speed, ct = tables_3x3[model].steady(direction, u, thrust_of_speed)
                assert np.abs(speed - v[f]).max() < 0.05
                assert ct == pytest.approx(thrust_of_speed(speed))


def test_combination_invariants(tables_3x3):
    tables = tables_3x3["gauss"]
    ct = np.full(9, 0.75)
    v = tables.waked_speeds(270.0, ct, 10.0)
    assert np.all(v <= 10.0) and v[[0, 3, 6]] == pytest.approx(10.0)
    assert tables.waked_speeds(270.0, np.zeros(9), 10.0) == pytest.approx(np.full(9, 10.0))
    weaker = tables.waked_speeds(270.0, np.full(9, 0.4), 10.0)
    assert np.all(weaker >= v) and np.all(weaker[[1, 2]] > v[[1, 2]] + 0.3)
    assert tables.waked_speeds(270.0 + 360.0, ct, 10.0) == pytest.approx(v)
    assert tables.waked_speeds(-90.0, ct, 10.0) == pytest.approx(v)
    # a per-pair thrust matrix with identical rows is the per-turbine thrust
    assert tables.waked_speeds(270.0, np.tile(ct[:, None], (1, 9)), 10.0) == pytest.approx(v)
    # a change of turbine 1's thrust that has reached turbine 2 but not yet turbine 3 (Jensen: no turbulence, so
    # turbine 2's own wake does not change with it; with Gauss it does, through turbine 2's added turbulence)
    jensen = tables_3x3["jensen"]
    before = jensen.waked_speeds(270.0, ct, 10.0)
    pair = np.tile(ct[:, None], (1, 9))
    pair[0, 1] = 0.3
    changed = jensen.waked_speeds(270.0, pair, 10.0)
    assert changed[1] > before[1] + 0.5 and changed[2] == pytest.approx(before[2], abs=1e-12)
    gauss_changed = tables.waked_speeds(270.0, pair, 10.0)
    assert gauss_changed[1] > v[1] + 0.5 and gauss_changed[2] < v[2]  # less added turbulence: a narrower wake
    # the free stream of each turbine scales its own speed
    free = np.linspace(9.0, 11.0, 9)
    assert tables.waked_speeds(270.0, ct, free) == pytest.approx(v / 10.0 * free)


def test_batch_equals_farm_by_farm(tables_3x3):
    """A batch of farms (Monte Carlo runs) with their own directions, thrusts and free streams is combined as each
    farm alone, whether the farms share a table interval or not."""
    rng = np.random.default_rng(5)
    directions = np.array([270.2, 270.7, 315.0, 92.5, 270.2])
    thrust = rng.uniform(0.2, 0.85, (5, 9, 9))
    free = rng.uniform(6.0, 14.0, (5, 9))
    for tables in tables_3x3.values():
        speed, ti = tables.waked(directions, thrust, free)
        for f in range(5):
            one = tables.waked(directions[f], thrust[f], free[f])
            assert np.allclose(speed[f], one[0], rtol=0, atol=1e-12) and np.allclose(ti[f], one[1], rtol=0, atol=1e-12)
        per_turbine = tables.waked(directions, thrust[:, :, 0], free[:, 0])[0]
        assert per_turbine[2] == pytest.approx(tables.waked_speeds(315.0, thrust[2, :, 0], free[2, 0]))


def test_the_compiled_combination_equals_the_reference(tables_3x3):
    """``plant_sim.farm.fast.wake_combine`` (the compiled backend's, ``wwcore.backend``) against
    ``WakeTables._combine`` for farms sharing a table interval: per-pair thrusts inside and outside the table's C_T
    range (negative, above its largest), free streams, Gauss (interpolated in TI) and Jensen; equal to the last bit."""
    fast = fast_module("plant_sim.farm.fast")
    rng = np.random.default_rng(11)
    farms = 6
    thrust = rng.uniform(-0.1, 1.0, (farms, 9, 9))
    free = rng.uniform(4.0, 20.0, (farms, 9))
    for direction in (270.0, 270.37, 313.9):
        for tables in tables_3x3.values():
            x = direction / tables.direction_step_deg
            entries = tables._bin(int(np.floor(x)))
            w = np.full(farms, x - np.floor(x))
            w[1] = 0.0
            reference = tables._combine(entries, w, thrust, free)
            constants = (tables._ct_max, tables._inv_s_step, tables._m_last, tables._inv_ti_step, tables.ambient_ti**2)
            flat = (tables.added_ti.reshape(-1), tables.deficit.reshape(-1), np.asarray(tables.ti_grid, dtype=float))
            speed, ti = np.empty((farms, 9)), np.empty((farms, 9))
            fast.wake_combine(entries, w, thrust, free, flat + constants, speed, ti)
            np.testing.assert_array_equal(ti, reference[1], f"{tables.model} {direction}: TI")
            np.testing.assert_array_equal(speed, reference[0], f"{tables.model} {direction}: speed")
            assert (speed < free).any()


def test_bad_inputs_are_refused(tables_3x3, seed001, cache):
    tables = tables_3x3["gauss"]
    with pytest.raises(ValueError, match=r"shape \(9,\) or \(9, 9\)"):
        tables.waked_speeds(270.0, np.zeros(8), 10.0)
    with pytest.raises(ValueError, match=r"shape \(2, 9\) or \(2, 9, 9\)"):
        tables.waked(np.array([270.0, 271.0]), np.zeros((3, 9)), 10.0)
    with pytest.raises(ValueError, match="does not divide 360"):
        floris_wakes.build_wake_tables(seed001, WakeSettings(direction_step_deg=0.7), BENCHMARK)
    other = FarmLayout(seed001.x * 2.0, seed001.y * 2.0, 2.0 * D)
    with pytest.raises(ValueError, match="the turbine's is 115"):
        wake_tables(other, WakeSettings(), BENCHMARK, cache)
    with pytest.raises(ValueError):
        WakeSettings(model="cosine")


def test_cache_round_trip_and_invalidation(seed001, tmp_path, monkeypatch, caplog):
    settings = WakeSettings(model="jensen", direction_step_deg=2.0)
    built = []
    real_build = floris_wakes.build_wake_tables

    def counting_build(*args, **kwargs):
        built.append(args[1])
        return real_build(*args, **kwargs)

    monkeypatch.setattr(floris_wakes, "build_wake_tables", counting_build)
    first = wake_tables(seed001, settings, BENCHMARK, tmp_path)
    second = wake_tables(seed001, settings, BENCHMARK, tmp_path)
    assert len(built) == 1  # the second start loaded the file
    files = list(tmp_path.glob("wakes-*.npz"))
    assert len(files) == 1 and first.key in files[0].name
    for name in ("bin_start", "upstream", "downstream", "thrust_grid", "ti_grid", "deficit", "added_ti", "covered"):
        assert np.array_equal(getattr(first, name), getattr(second, name))
    assert second.settings_json == settings.model_dump_json()
    # any change of settings or geometry is a new key
    wake_tables(seed001, settings.model_copy(update={"turbulence_intensity": 0.06}), BENCHMARK, tmp_path)
    moved = FarmLayout(seed001.x + np.r_[1.0, np.zeros(8)], seed001.y, D)
    wake_tables(moved, settings, BENCHMARK, tmp_path)
    assert len(built) == 3 and len(list(tmp_path.glob("wakes-*.npz"))) == 3
    # a damaged file is rebuilt, with a warning
    files[0].write_bytes(b"not a table")
    with caplog.at_level(logging.WARNING, logger="plant_sim.farm.floris_wakes"):
        again = wake_tables(seed001, settings, BENCHMARK, tmp_path)
    assert len(built) == 4 and "rebuilding" in caplog.text
    assert np.array_equal(again.deficit, first.deficit)
    with pytest.raises(ValueError, match="is not"):
        WakeTables.load(files[0], key="0" * 32)


def test_a_cached_table_loads_without_importing_floris(tmp_path):
    """A farm whose wake tables are cached starts without importing FLORIS (``plant_sim.farm.wake_cache``: every
    process of an evaluation loads the tables; FLORIS's import took about 0.65 CPU-s and 2 s of wall time in each),
    and the cache key is the one FLORIS's module computed with ``floris.__version__``, so tables cached before load."""
    scenario = load_scenario("farm-case1")
    built = plant_wake_tables(scenario.plant, scenario.wind, BENCHMARK, tmp_path)  # built by FLORIS, cached
    script = (
        "import sys\n"
        "from plant_sim.farm.wakes import plant_wake_tables\n"
        "from wwcore.scenario import load_scenario\n"
        "from wwcore.turbine_params import BENCHMARK\n"
        "s = load_scenario('farm-case1')\n"
        f"t = plant_wake_tables(s.plant, s.wind, BENCHMARK, {str(tmp_path)!r})\n"
        "print(t.key, 'floris' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout.split()
    assert out == [built.key, "False"]
    settings = WakeSettings.model_validate_json(built.settings_json)
    layout = scenario.plant.resolved_layout()
    identity = {"settings": settings.model_dump(), "hub": BENCHMARK.hub_height, "floris": floris.__version__}
    digest = hashlib.sha256(layout.fingerprint())
    digest.update(json.dumps({**identity, "format": FORMAT_VERSION}, sort_keys=True).encode())
    assert wake_cache.cache_key(layout, settings, BENCHMARK) == digest.hexdigest()[:32] == built.key
