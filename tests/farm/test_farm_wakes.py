"""FLORIS wakes in the farm plant (plant_sim.farm.wakes): steady winds against direct FLORIS runs, the travel delay
of a derated turbine's wake, any layout in the plant alone, and the row model unchanged bit for bit.

The plant's steady per-turbine winds are its wake model's mean winds (``truth()["row_wind"]``) averaged once every
pair's delayed thrust comes from the running turbines (past the longest travel time), with the shared slow
turbulence off; FLORIS runs the same layout and direction with the benchmark turbine's curves at the same ambient
turbulence intensity.
"""

from __future__ import annotations

import numpy as np
import pytest

from plant_sim.farm import FarmBatch
from plant_sim.farm.floris_wakes import floris_model
from plant_sim.farm.operating_curve import rated_curve
from tests.numeric_fingerprint import NumericFingerprint, expected, mismatches
from wwcore.farm_frames import FarmRefs
from wwcore.scenario.farm import FarmDemand, FarmPlant
from wwcore.scenario.faults import FaultSpec
from wwcore.scenario.loader import ScenarioError, load_scenario, parse_scenario
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_params import BENCHMARK

TI = 0.10
# ``rows_fingerprint()``'s expected sums (``tests/data/numeric_fingerprints.json``, ``farm_rows``) are the code's
# before the FLORIS wakes were wired in: this function's SHA-256 equalled that code's (main at cea9ec2) on the
# machine CI ran on through main at b2a8282, and the sums were taken from b2a8282's code on a CPU with AVX-512,
# whose SIMD rounding moves the raw bits (``tests/numeric_fingerprint.py``).


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("wake-tables")


def plant_spec(case: int = 1, model: str = "gauss", **kw) -> FarmPlant:
    demand = kw.pop("demand", FarmDemand(mode="profile", points=[(0.0, 40.0)]))
    return FarmPlant(wind_case=case, wake_model=model, coherent_ti=0.0, demand=demand, **kw)


def direct_floris(spec: FarmPlant, model: str, speeds, ti: float = TI):
    speeds = np.atleast_1d(np.asarray(speeds, dtype=float))
    fm = floris_model(spec.resolved_layout(), model, BENCHMARK, np.full(len(speeds), spec.direction_deg), speeds, ti)
    fm.run()
    return fm


def steady_plant_winds(spec: FarmPlant, speed: float, ti: float, seconds: float, average_s: float, cache) -> np.ndarray:
    """Each turbine's mean wind averaged over the last ``average_s`` of a ``seconds`` run at ``speed`` m/s."""
    plant = FarmBatch(
        spec,
        WindSpec(mean=[(0.0, speed)], turbulence_intensity=ti),
        [],
        seed=7,
        duration_s=seconds,
        wake_cache_dir=cache,
    )
    winds = []
    for k in range(round(seconds / plant.dt)):
        frame = plant.measure()
        plant.control(None)
        if frame.sample and (k + 1) * plant.dt > seconds - average_s:
            winds.append(plant.truth()["row_wind"])
        plant.advance()
    return np.mean(winds, axis=0)


# ---- steady winds against FLORIS ---------------------------------------------------------------------------------
STEADY_TI = 0.03  # –, the turbines' own turbulence nearly off (and the wakes' ambient TI, FLORIS's too)
SPEED = 9.0  # m/s
RUN_S = {1: 200.0, 2: 280.0}  # s, past the longest travel time of each case


@pytest.fixture(scope="module")
def running_3x3(cache):
    """Both wind cases at 9 m/s (C_T 0.74), run past the longest travel time (case 1: 1610 m / 9 m/s = 179 s;
    case 2: 2277 m / 9 m/s = 253 s), averaged over the last 20 s.

    The turbines' own turbulence moves their C_T (a turbine in a gust near rated pitches and sheds thrust), which
    FLORIS's steady model does not know: at 12 m/s with TI 0.10 turbine 5 of case 1 sits 0.13 m/s above FLORIS.
    Hence TI 0.03, a speed where the C_T curve is flat, and no wake-added turbulence on the turbines (at TI 0.03
    FLORIS's wake-added turbulence makes a waked turbine's 2.1-2.3 times the ambient).
    """
    specs = {case: plant_spec(case, wake_added_turbulence=False) for case in RUN_S}
    return {case: steady_plant_winds(specs[case], SPEED, STEADY_TI, secs, 20.0, cache) for case, secs in RUN_S.items()}


@pytest.mark.slow
@pytest.mark.parametrize("case", [1, 2])
def test_running_plant_steady_winds_equal_floris_gauss(running_3x3, case):
    ref = direct_floris(plant_spec(case), "gauss", SPEED, STEADY_TI).turbine_average_velocities[0]
    assert np.abs(running_3x3[case] - ref).max() < 0.1  # m/s (issue 24)
    assert ref.min() < SPEED - 1.0  # the farm is waked: the comparison is not between two free streams


@pytest.mark.slow
def test_case2_wakes_only_the_turbines_floris_wakes(running_3x3):
    ref = direct_floris(plant_spec(2), "gauss", SPEED, STEADY_TI).turbine_average_velocities[0]
    free = ref > SPEED - 0.05
    assert list(np.flatnonzero(free) + 1) == [1, 2, 3, 4, 7]  # FLORIS: the front and the two free edges
    got = running_3x3[2]
    assert np.all(np.abs(got[free] - SPEED) < 0.05)
    assert np.all(got[~free] < SPEED - 0.5)


@pytest.mark.parametrize("model", ["gauss", "jensen"])
@pytest.mark.parametrize("case", [1, 2])
def test_initial_state_and_available_power_equal_floris(cache, model, case):
    """t = 0 is the steady state: winds and (delta control) available power as FLORIS's, at 8 and 14 m/s
    (``tools/compare_wakes.py`` adds 11 m/s)."""
    for speed in (8.0, 14.0):
        spec = plant_spec(case, model, demand=FarmDemand(mode="available_fraction", fraction=0.8))
        plant = FarmBatch(
            spec, WindSpec(mean=[(0.0, speed)], turbulence_intensity=TI), [], seed=1, duration_s=1.0,
            wake_cache_dir=cache,
        )  # fmt: skip
        fm = direct_floris(spec, model, speed)
        assert np.abs(plant.field.turbine_wind[0] - fm.turbine_average_velocities[0]).max() < 0.05
        assert plant.demand[0, 0] == pytest.approx(0.8 * fm.get_farm_power()[0], rel=0.01)


def test_a_derated_turbine_casts_a_weaker_wake_one_travel_time_later(cache):
    """Turbine 1 derated to 1 MW at t = 2 s (case 1, 14 m/s): turbine 2, 805 m behind, sees it 805/14 = 57.5 s on."""
    spec = plant_spec(1)
    plant = FarmBatch(
        spec, WindSpec(mean=[(0.0, 14.0)], turbulence_intensity=0.02), [], seed=3, duration_s=75.0,
        wake_cache_dir=cache,
    )  # fmt: skip
    refs = np.full(plant.n, BENCHMARK.rated_power)
    refs[0] = 1.0e6
    wind2 = []
    for k in range(round(75.0 / plant.dt)):
        frame = plant.measure()
        plant.control(FarmRefs(0, refs) if k * plant.dt >= 2.0 else None)
        if frame.sample:
            wind2.append(plant.truth()["row_wind"][1])
        plant.advance()
    wind2 = np.array(wind2)  # one per 0.1 s, the first at t = 0.1 s
    before = wind2[: round(55.0 / 0.1)]
    assert np.ptp(before) < 0.02  # nothing reached turbine 2 yet (turbulence 0.02: C_T barely moves)
    assert wind2[-50:].mean() > before.mean() + 0.3  # the weaker wake has arrived


def test_waked_turbines_get_floris_wake_added_turbulence(cache):
    """With ``wake_added_turbulence`` each turbine's own turbulence is σ × TI_t/TI_0, TI_t FLORIS's at the turbine:
    the same random streams with and without it differ by exactly that factor (the means are equal until a changed
    C_T has travelled to the next row, 805 m / 9 m/s = 89 s)."""

    def hub_deviation(added: bool) -> np.ndarray:
        spec = plant_spec(1, wake_added_turbulence=added)
        wind = WindSpec(mean=[(0.0, 9.0)], turbulence_intensity=TI)
        plant = FarmBatch(spec, wind, [], seed=4, duration_s=5.0, wake_cache_dir=cache)
        out = []
        for _ in range(500):
            plant.measure()
            plant.control(None)
            truth = plant.turbines.truth()
            out.append(truth["wind_hub"] - truth["wind_mean"])
            plant.advance()
        return np.array(out)

    ratio = np.median(hub_deviation(True) / hub_deviation(False), axis=0)
    expected = direct_floris(plant_spec(1), "gauss", 9.0).get_turbine_TIs()[0] / TI
    assert ratio == pytest.approx(expected, rel=0.02)
    assert ratio[[0, 3, 6]] == pytest.approx(1.0, abs=1e-9)  # the front row sees the ambient turbulence
    assert np.all(ratio[[1, 2, 4, 5, 7, 8]] > 1.1)  # FLORIS: 1.22 and 1.20


# ---- any layout in the plant alone -------------------------------------------------------------------------------
@pytest.mark.slow
def test_horns_rev_1_plant_runs_80_turbines_with_floris_winds(cache):
    spec = FarmPlant(
        wake_model="gauss", layout={"kind": "file", "name": "hornsrev1"}, wind_direction_deg=270.0, coherent_ti=0.0,
        demand=FarmDemand(mode="profile", points=[(0.0, 300.0)]),
    )  # fmt: skip
    assert spec.n_turbines == 80
    plant = FarmBatch(
        spec, WindSpec(mean=[(0.0, 9.0)], turbulence_intensity=TI), [], seed=2, duration_s=2.0, wake_cache_dir=cache
    )
    ref = direct_floris(spec, "gauss", 9.0).turbine_average_velocities[0]
    assert np.abs(plant.field.turbine_wind[0] - ref).max() < 0.1
    for _ in range(200):  # 2 s of the 100 Hz loop
        plant.measure()
        plant.control(None)
        plant.advance()
    assert plant.turbines.n == 80 and np.all(np.isfinite(plant.power_output()))
    assert np.abs(plant.truth()["row_wind"] - ref).max() < 0.1


def test_a_single_turbine_farm_sees_the_free_stream(cache):
    spec = FarmPlant(
        wake_model="jensen", layout={"kind": "coordinates", "x_m": [0.0], "y_m": [0.0]}, wind_direction_deg=200.0,
        demand=FarmDemand(mode="profile", points=[(0.0, 4.0)]),
    )  # fmt: skip
    plant = FarmBatch(spec, WindSpec(mean=[(0.0, 9.0)]), [], seed=2, duration_s=1.0, wake_cache_dir=cache)
    for _ in range(50):
        plant.measure()
        plant.control(None)
        plant.advance()
    truth = plant.truth()
    assert truth["row_wind"] == pytest.approx(truth["free_wind"])
    assert plant.n == 1


# ---- the scenario section ----------------------------------------------------------------------------------------
def _farm_scenario(**plant) -> dict:
    return {"name": "farm-wakes", "duration_s": 100.0, "plant": {"kind": "farm", **plant}}


@pytest.mark.parametrize(
    "plant, field, words",
    [
        ({"wake_model": "floris"}, "plant.wake_model", "'rows', 'gauss' or 'jensen'"),
        ({"wake_model": "rows", "layout": {"kind": "file", "name": "hornsrev1"}}, "plant", "row model"),
        ({"wake_model": "gauss", "layout": {"kind": "file", "name": "hornsrev1"}}, "plant", "wind_direction_deg"),
        ({"wake_model": "rows", "wind_direction_deg": 300.0}, "plant", "two wind cases"),
        ({"wake_model": "rows", "wake_added_turbulence": False}, "plant", "no wake-added turbulence"),
        (
            {
                "wake_model": "gauss",
                "layout": {"kind": "file", "name": "hornsrev1"},
                "wind_direction_deg": 270.0,
                "spacing_m": 700.0,
            },
            "plant",
            "the layout gives the positions",
        ),
        ({"wake_model": "gauss", "layout": {"kind": "file", "name": "nowhere"}}, "plant.layout", "no layout file"),
        (
            {
                "wake_model": "gauss",
                "layout": {"kind": "coordinates", "x_m": [0, 100], "y_m": [0, 0]},
                "wind_direction_deg": 270.0,
            },
            "plant.layout",
            "overlap",
        ),
    ],
)
def test_bad_wake_or_layout_settings_are_refused_with_a_clear_message(plant, field, words):
    with pytest.raises(ScenarioError) as err:
        parse_scenario(_farm_scenario(**plant))
    fields = [f for f, _ in err.value.problems]
    assert any(f.startswith(field) for f in fields), fields
    assert words in str(err.value)


def test_a_dumped_plant_section_reads_back_the_same():
    """The live adapter and the scorecard dump the plant section and read it again: every form must survive."""
    forms = [
        {},
        {"wake_model": "gauss", "wake_added_turbulence": False},
        {"wake_model": "jensen", "layout": {"kind": "file", "name": "hornsrev1"}, "wind_direction_deg": 222.0},
        {"wake_model": "gauss", "layout": {"kind": "grid", "rows": 2, "columns": 5}, "wind_direction_deg": 10.0},
    ]
    for form in forms:
        plant = FarmPlant(**form)
        assert FarmPlant.model_validate(plant.model_dump()) == plant
        assert FarmPlant.model_validate_json(plant.model_dump_json()) == plant


def test_the_papers_farm_given_as_a_layout_is_the_papers_farm():
    seed001 = {"kind": "file", "name": "seed001_3x3"}
    scenario = parse_scenario(_farm_scenario(wake_model="gauss", layout=seed001, wind_direction_deg=315.0, wind_case=2))
    assert scenario.plant.rows() == FarmPlant(wind_case=2).rows()
    assert parse_scenario(_farm_scenario(wake_model="jensen")).plant.wake_model == "jensen"
    assert parse_scenario(_farm_scenario()).plant.wake_model == "gauss"  # FLORIS's Gauss wakes unless told
    for name in ("farm-case1", "farm-case2", "farm-case1-mismatch", "farm-fault-free-case2"):
        assert load_scenario(name).plant.wake_model == "gauss", name


# ---- the row model is unchanged ----------------------------------------------------------------------------------
def rows_fingerprint(seconds: float = 20.0) -> dict:
    """The numeric fingerprint (``tests/numeric_fingerprint.py``) of short runs of the row model: case 1 with twins,
    debris and a derated turbine, case 2 with row coherence, a wind ramp and a demand profile (every 10 Hz sample's
    power, winds, mast, demand and SCADA)."""
    debris = FaultSpec(target="rotor", kind="debris", value=0.97, turbine=5, start_s=3.0)
    a = FarmBatch(
        FarmPlant(
            wind_case=1, wake_model="rows", demand=FarmDemand(mode="available_fraction", fraction=0.8, update_s=10.0)
        ),
        WindSpec(mean=[(0.0, 9.0)], turbulence_intensity=0.1), [debris], seed=11, duration_s=20.0, runs=(0, 1),
        fault_free_twins=True,
    )  # fmt: skip
    b = FarmBatch(
        FarmPlant(
            wind_case=2,
            wake_model="rows",
            row_coherence=0.4,
            demand=FarmDemand(mode="profile", points=[(0.0, 20.0), (10.0, 30.0)]),
        ),
        WindSpec(mean=[(0.0, 8.0), (20.0, 14.0)], turbulence_intensity=0.12), [], seed=12, duration_s=20.0,
    )  # fmt: skip
    digest = NumericFingerprint()
    for p, plant in enumerate((a, b)):
        digest.update(f"{p}:demand", plant.demand)
        ref = np.full(plant.n, 4.8e6)
        ref[0] = 2.5e6
        for k in range(round(seconds / plant.dt)):
            frame = plant.measure()
            plant.control(FarmRefs(0, ref) if k >= 500 else None)
            if frame.sample:
                truth = plant.truth()
                for name, arr in (("power", plant.power_output()), ("row_wind", truth["row_wind"]),
                                  ("free_wind", truth["free_wind"]), ("mast", frame.mast),
                                  ("demand_sample", frame.demand), ("scada", frame.scada)):  # fmt: skip
                    digest.update(f"{p}:{name}", arr)
            plant.advance()
    return digest.values()


def test_the_row_model_is_bit_identical_to_the_code_before_floris_wakes():
    assert not mismatches(rows_fingerprint(), expected("farm_rows"))


def test_the_rated_curve_is_the_one_floris_turbine_follows():
    winds, power, ct = rated_curve(BENCHMARK)
    fm = direct_floris(plant_spec(1), "gauss", [8.0, 11.0, 14.0])
    assert fm.get_turbine_thrust_coefficients()[:, 0] == pytest.approx(np.interp([8.0, 11.0, 14.0], winds, ct))
    assert power.max() == pytest.approx(BENCHMARK.rated_power, rel=1e-3)
