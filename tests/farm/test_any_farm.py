"""The farm supervisor for any layout: N and the positions from the site, detection on the right turbine of small
farms that are not the 3 × 3, the paper's rows from a direction and the layout (hand-worked), the dispatch sharing
the demand over N turbines, the vane, and what is still refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plant_sim.farm import FarmBatch
from service.farm.analytic import AnalyticDetector
from service.farm.dispatch import Dispatch
from service.farm.interfaces import FarmContext, FarmSample
from service.farm.paper import PaperDetector
from service.farm.supervisor import FarmSupervisor
from tests.farm.conftest import detections, simulate, wind
from windwarden.cli import main
from windwarden.evaluation.farm_scoring import PowerBalance
from windwarden.kinds.farm import FARM
from wwcore.channels import N_SENSORS
from wwcore.scenario import ScenarioError, parse_scenario
from wwcore.scenario.farm import FarmDemand, FarmPlant
from wwcore.scenario.faults import FaultSpec

PROFILE = FarmDemand(mode="profile", points=[(0.0, 3.0)])


def layout_farm(layout: dict, direction: float, demand_mw: float) -> FarmPlant:
    """A farm of ``layout`` without wakes (no FLORIS tables to build: the supervisor is what is tested)."""
    demand = FarmDemand(mode="profile", points=[(0.0, demand_mw)])
    return FarmPlant(wake_model="gauss", wakes=False, layout=layout, wind_direction_deg=direction, demand=demand)


GRID_2X5 = {"kind": "grid", "rows": 2, "columns": 5, "column_spacing_d": 5.0, "row_spacing_d": 7.0}
THREE = {"kind": "coordinates", "x_m": [0.0, 600.0, 250.0], "y_m": [0.0, 80.0, -700.0]}


# ---- the site and the context ------------------------------------------------------------------------------------
def test_the_site_gives_the_number_and_positions_of_the_layout():
    plant = layout_farm(THREE, 200.0, 6.0)
    site = plant.site()
    assert site.turbines == (1, 2, 3)
    assert site.positions_m == ((0.0, 0.0), (600.0, 80.0), (250.0, -700.0))
    context = FarmContext(site, 6)
    assert (context.turbines, context.farms, context.paper_grid) == (3, 2, False)
    assert FarmContext(FarmPlant().site(), 18).paper_grid
    with pytest.raises(ValueError, match="whole farms of 3"):
        FarmContext(site, 7)


# ---- detection on the right turbine of farms that are not the 3 × 3 -----------------------------------------------
@pytest.mark.parametrize(
    ("layout", "direction", "demand_mw", "fault", "name"),
    [
        (  # one turbine
            {"kind": "coordinates", "x_m": [0.0], "y_m": [0.0]},
            123.0,
            3.0,
            FaultSpec(target="rotor", kind="debris", value=0.97, turbine=1, start_s=15.0),
            "debris",
        ),
        (  # 2 × 5 grid, oblique wind
            GRID_2X5,
            250.0,
            30.0,
            FaultSpec(target="rotor", kind="debris", value=0.97, turbine=7, start_s=15.0),
            "debris",
        ),
        (  # three turbines at explicit coordinates
            THREE,
            200.0,
            9.0,
            FaultSpec(target="pitch_actuator_2", kind="offset", value=0.3, turbine=3, start_s=15.0),
            "pitch_misalignment",
        ),
    ],
)
def test_the_supervisor_flags_the_right_turbine_of_any_farm(layout, direction, demand_mw, fault, name):
    plant_spec = layout_farm(layout, direction, demand_mw)
    _, sup, events = simulate(plant_spec, wind(10.0), [fault], 22.0, seed=5)
    assert sup.context.turbines == plant_spec.n_turbines
    hits = detections(events)
    assert hits, "not detected"
    assert {(e.turbine, e.target) for e in hits} == {(fault.turbine, name)}
    assert min(e.t for e in hits) - fault.start_s < 3.0


def test_the_analytic_budget_is_the_farms_and_grows_with_ln_n():
    """h = ln(10⁴ · N · m / B): 80 turbines sit ln(80/9) above the 3 × 3's, one turbine ln 9 below."""

    def h1(site, n):
        return AnalyticDetector(context=FarmContext(site, n)).h1

    nine = h1(FarmPlant().site(), 9)
    hr1 = FarmPlant(wake_model="gauss", layout={"kind": "file", "name": "hornsrev1"}, wind_direction_deg=270.0)
    one = layout_farm({"kind": "coordinates", "x_m": [0.0], "y_m": [0.0]}, 0.0, 1.0)
    assert h1(hr1.site(), 80) - nine == pytest.approx(math.log(80 / 9))
    assert nine - h1(one.site(), 1) == pytest.approx(math.log(9))


# ---- the paper's rows from a direction and the layout ---------------------------------------------------------
def test_paper_rows_of_the_two_wind_cases_from_the_direction():
    context = FarmContext(FarmPlant().site(), 9)
    assert context.rows(270.0) == [(1, 4, 7), (2, 5, 8), (3, 6, 9)]
    assert context.rows(315.0) == [(1,), (2, 4), (3, 5, 7), (6, 8), (9,)]
    s = 805.0
    assert context.row_distances_m(315.0) == pytest.approx(
        [0, s / math.sqrt(2), s * math.sqrt(2), 1.5 * s * math.sqrt(2), 2 * s * math.sqrt(2)]
    )


def test_paper_rows_of_an_oblique_wind_by_hand():
    """Wind from 243.435° (tan⁻¹ ½ south of west) on the 3 × 3: s ∝ 2·column − row, 360 m a step, so the rows are
    the turbines with equal 2c − r: −2 {7}, −1 {4}, 0 {1, 8}, 1 {5}, 2 {2, 9}, 3 {6}, 4 {3}."""
    context = FarmContext(FarmPlant().site(), 9)
    direction = 270.0 - math.degrees(math.atan(0.5))
    assert context.rows(direction) == [(7,), (4,), (1, 8), (5,), (2, 9), (6,), (3,)]
    step = 805.0 / math.sqrt(5.0)
    assert context.row_distances_m(direction) == pytest.approx([k * step for k in range(7)])


def test_paper_rows_split_where_the_line_leaves_the_tolerance():
    """Wind from 273°: each grid row adds 805 sin 3° = 42.1 m along the wind. Turbines 1 and 4 are 42.1 m apart
    (inside 0.5 D = 57.5 m), 1 and 7 are 84.3 m apart: {1, 4}, {7}, and so on down the columns."""
    context = FarmContext(FarmPlant().site(), 9)
    assert context.rows(273.0) == [(1, 4), (7,), (2, 5), (8,), (3, 6), (9,)]
    assert context.rows(272.0) == [(1, 4, 7), (2, 5, 8), (3, 6, 9)]  # 2 × 28.1 m = 56.2 m: still one row


def _vane_sample(j: int, direction: np.ndarray, n: int) -> FarmSample:
    farms = len(direction)
    scada = np.zeros((n, N_SENSORS))
    scada[:, -1] = 2e6
    return FarmSample(
        j, j * 0.1, scada, np.zeros(n, dtype=np.int8), np.zeros(n), np.full(farms, 10.0), np.full(farms, 1e7), direction
    )


def test_paper_rows_follow_the_vane_and_regroup_when_the_direction_moves():
    site = layout_farm(GRID_2X5, 0.0, 30.0).site()
    context = FarmContext(site, 20)
    det = PaperDetector(context=context)
    assert not det.from_power
    # grid rows run west → east, the second south of the first (orientation 90°): wind from the south meets the
    # second grid row first; wind from the east meets the east column (5, 10) first
    directions = np.array([180.0, 90.0])
    for j in range(500):
        det.step(_vane_sample(j, directions, 20))
    assert det.direction == pytest.approx(directions, abs=1e-6)
    assert det.rows[0] == context.rows(180.0) == [(6, 7, 8, 9, 10), (1, 2, 3, 4, 5)]
    assert det.rows[1] == context.rows(90.0) == [(5, 10), (4, 9), (3, 8), (2, 7), (1, 6)]
    for j in range(500, 1500):  # farm 1's wind veers to 100°: the rows are formed again past regroup_deg
        det.step(_vane_sample(j, np.array([180.0, 100.0]), 20))
    assert det.grouped[1] > 95.0 and det.rows[0] == context.rows(180.0)


def test_the_vane_estimate_averages_every_reading_before_the_rows_are_first_formed():
    """A first reading 10° off weighs 1/500 when the rows are formed (50 s), not e^(−50/60) as a first-order filter
    started from it would leave (4.3°)."""
    det = PaperDetector(context=FarmContext(layout_farm(GRID_2X5, 0.0, 30.0).site(), 10))
    for j in range(500):
        det.step(_vane_sample(j, np.array([280.0 if j == 0 else 270.0]), 10))
    assert det.direction[0] == pytest.approx(270.0 + 10.0 / 500.0, abs=1e-3)


def test_the_plant_vane_reads_the_direction_with_its_noise_and_leaves_the_other_streams_alone():
    spec = layout_farm({"kind": "coordinates", "x_m": [0.0, 500.0], "y_m": [0.0, 0.0]}, 250.0, 6.0)
    quiet = spec.model_copy(update={"mast_direction_noise_deg": 0.0})
    readings, speeds = [], []
    for plant_spec in (spec, quiet):
        plant = FarmBatch(plant_spec, wind(10.0), [], seed=4, duration_s=21.0)
        got, mast = [], []
        for _ in range(2000):
            frame = plant.measure()
            plant.control(None)
            if frame.sample:
                got.append(frame.mast_direction[0])
                mast.append(frame.mast[0])
            plant.advance()
        readings.append(np.array(got))
        speeds.append(np.array(mast))
    error = (readings[0] - 250.0 + 180.0) % 360.0 - 180.0
    assert abs(error.mean()) < 1.0 and error.std() == pytest.approx(5.0, rel=0.15)
    assert np.all(readings[1] == 250.0)
    assert np.array_equal(speeds[0], speeds[1])  # the vane's noise is a stream of its own


# ---- the dispatch over N turbines -----------------------------------------------------------------------------
@pytest.mark.parametrize("rule", ["cancel", "paper"])
def test_the_dispatch_shares_the_demand_over_n_turbines(rule):
    """Eq. (18) over 80 turbines: with the power trim off the output asked of the farm is its demand, whatever the
    flags (a debris turbine is sent P/0.97 to make its share, eqs. (23)–(24); derated ones give theirs to others)."""
    hr1 = FarmPlant(wake_model="gauss", layout={"kind": "file", "name": "hornsrev1"}, wind_direction_deg=270.0)
    farms, per_farm = 2, 80
    context = FarmContext(hr1.site(), farms * per_farm)
    options = {"trim_kp": 0.0, "trim_ki": 0.0, "ripple_compensation": False, "accommodation_rule": rule}
    dispatch = Dispatch(context=context, options=options)
    rng = np.random.default_rng(7)
    avail = rng.uniform(0.5e6, 4.8e6, farms * per_farm)
    dispatch.estimate_available = lambda sample: avail  # eqs. (20)–(22) are tested elsewhere
    demand = np.array([0.6, 0.9]) * avail.reshape(farms, per_farm).sum(axis=1)
    sample = FarmSample(
        0, 0.0, np.zeros((farms * per_farm, N_SENSORS)), np.zeros(farms * per_farm, dtype=np.int8),
        np.zeros(farms * per_farm), np.full(farms, 10.0), demand,
    )  # fmt: skip
    faulty = np.zeros((farms * per_farm, 3), dtype=bool)
    faulty[[3, 80 + 41], 0] = True  # debris on turbine 4 of farm 0 and 42 of farm 1
    faulty[[17, 80 + 66], 2] = True  # drive train on turbine 18 of farm 0 and 67 of farm 1
    refs = dispatch.step(sample, faulty).reshape(farms, per_farm)
    made = refs * np.where(faulty[:, 0], 0.97, 1.0).reshape(farms, per_farm)
    assert made.sum(axis=1) == pytest.approx(demand, rel=1e-12)
    assert np.all(refs >= 0.0) and np.all(refs <= 4.8e6)
    modes = dispatch.mode.reshape(farms, per_farm)
    assert modes[0, 3] == modes[1, 41] == 1  # debris
    if rule == "paper":
        assert modes[0, 17] == modes[1, 66] == 2 and refs[0, 17] < avail[17]  # derated by eq. (26)


def test_power_balance_counts_the_farms_of_n_turbines():
    balance = PowerBalance(rows=2 * 80, ticks_per_sample=1, turbines=80)
    demand = np.array([80e6, 100e6])
    for k in range(601):
        p_farm = balance.tick(k, np.full(160, 1e6), True, demand)
    assert p_farm == pytest.approx([80e6, 80e6])
    assert balance.missing == pytest.approx([0.0, 20e6 * 0.1 * 1])


def test_power_balance_by_blocks_sums_as_tick_by_tick():
    """``PowerBalance.block`` (the evaluation's, a farm sample's ticks at once) gives the ticks' numbers bit for bit,
    the blocks of a sample split anyhow."""
    rng = np.random.default_rng(84602)
    rows, per_sample, samples = 2 * 9, 10, 700
    power = rng.uniform(0.0, 5e6, (samples * per_sample, rows)) * rng.uniform(0.5, 1.5, rows)
    demand = rng.uniform(20e6, 40e6, (samples, 2))
    by_tick, by_block = (PowerBalance(rows, per_sample, 9) for _ in range(2))
    for k in range(len(power)):
        by_tick.tick(k, power[k], (k + 1) % per_sample == 0, demand[k // per_sample])
    for first in range(0, len(power), per_sample):
        cut = first + (3 if first // per_sample % 2 else per_sample)  # some samples as two blocks
        for start, end in ((first, cut), (cut, first + per_sample)):
            if end > start:
                end_sample = end == first + per_sample
                by_block.block(end - 1, power[start:end], end_sample, demand[first // per_sample])
    for name in ("over", "missing", "demand", "power_sum"):
        assert getattr(by_block, name).tobytes() == getattr(by_tick, name).tobytes()


# ---- what is still refused -----------------------------------------------------------------------------------
def _layout_scenario(**supervisor) -> dict:
    return {
        "name": "refused",
        "duration_s": 100.0,
        "plant": {"kind": "farm", "wake_model": "gauss", "layout": GRID_2X5, "wind_direction_deg": 250.0},
        "supervisor": supervisor,
    }


def test_a_layout_scenario_loads_and_the_wind_case_option_is_refused_there():
    assert parse_scenario(_layout_scenario()).plant.n_turbines == 10
    with pytest.raises(ScenarioError) as err:
        parse_scenario(_layout_scenario(detector="paper", params={"wind_case": 1}))
    assert [f for f, _ in err.value.problems] == ["supervisor.params.wind_case"]
    assert "wind_direction_deg" in str(err.value)
    ok = parse_scenario(_layout_scenario(detector="paper", params={"wind_direction_deg": 250.0}))
    assert ok.supervisor.params == {"wind_direction_deg": 250.0}


def test_a_wind_case_with_another_farm_or_direction_is_refused():
    data = _layout_scenario()
    data["plant"]["wind_case"] = 2
    with pytest.raises(ScenarioError) as err:
        parse_scenario(data)
    assert "wind_case" in str(err.value) and "wind_direction_deg" in str(err.value)
    seed001 = {"kind": "file", "name": "seed001_3x3"}
    paper = {"kind": "farm", "wake_model": "gauss", "layout": seed001, "wind_direction_deg": 315.0, "wind_case": 2}
    assert parse_scenario({"name": "p", "duration_s": 10.0, "plant": paper}).plant.is_paper_farm()


def test_the_paper_detector_refuses_the_3x3_direction_test_on_another_layout():
    site = layout_farm(GRID_2X5, 250.0, 30.0).site()
    with pytest.raises(ValueError, match="direction_source"):
        FarmSupervisor(site, 10, detector="paper", options={"direction_source": "power"})
    with pytest.raises(ValueError, match="wind_case"):
        PaperDetector(context=FarmContext(site, 10), options={"wind_case": 2})


def test_the_cli_refuses_the_wind_case_on_a_layout_with_exit_2(tmp_path, capsys):
    path = tmp_path / "refused.toml"
    path.write_text(
        'name = "refused"\nduration_s = 100.0\n[plant]\nkind = "farm"\nwake_model = "gauss"\n'
        'wind_direction_deg = 250.0\nlayout = { kind = "grid", rows = 2, columns = 5 }\n[supervisor]\n'
        'detector = "paper"\n[supervisor.params]\nwind_case = 1\n'
    )
    out = tmp_path / "out"
    assert main(["eval", str(path), "--runs", "1", "--quiet", "--out", str(out)]) == 2
    said = capsys.readouterr()
    assert "supervisor.params.wind_case" in said.err + said.out
    assert not out.exists()


def test_the_wire_carries_a_farm_of_n_turbines_and_its_vane():
    """``farm.sensors`` records of a three-turbine farm read back as the frame they were made from."""
    kind = FARM
    plant = FarmBatch(layout_farm(THREE, 200.0, 9.0), wind(10.0), [], seed=2, duration_s=2.0)
    turbines = kind.turbines(plant)
    for _ in range(10):
        frame = plant.measure()
        plant.control(None)
        plant.advance()
    assert frame.sample and turbines == [1, 2, 3]
    back = kind.frame_from_records(kind.frame_records(frame, turbines))
    for name in ("mast", "demand", "mast_direction", "scada", "power_ref_used"):
        assert np.array_equal(getattr(back, name), getattr(frame, name)), name
